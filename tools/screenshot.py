"""Screenshot a flight recording in Rerun's web viewer, headless (no GPU, no display): ``make screenshot``.

Usage: ``python -m tools.screenshot [--recording FLIGHT.rrd ...] [--out docs/recording_web_viewer.png]``.
Without ``--recording`` it first flies ``missions/city_block_delivery.yaml`` (``tools.run`` at
``--speed max``, about a minute) and uses that flight's recording. Several files are served together, as
``rerun`` opens them: a fleet's recording is ``--recording runs/fleet-<timestamp>/*.rrd``.

How: ``rerun --serve-web`` serves the recording and the web viewer on two free loopback ports; Chromium
renders the viewer headless with its software rasterizer (SwiftShader) and writes the PNG. The viewer
loads its WebAssembly after the page's load event, so the page Chromium opens is a wrapper holding the
viewer in a frame plus one image this script answers only after ``--wait-s`` seconds: Chromium takes the
screenshot at the wrapper's load event, when the viewer has drawn the flight.

Needs Chromium (Debian: ``apt-get update && apt-get install -y chromium``); exit status 2 with one line
saying so when it is missing, 1 when no screenshot was written.
"""

from __future__ import annotations

import argparse
import http.server
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
from collections.abc import Sequence
from pathlib import Path

from autopilot.launch_processes import stop_group

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO_ROOT / "docs" / "recording_web_viewer.png"
DEFAULT_MISSION = REPO_ROOT / "missions" / "city_block_delivery.yaml"
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: A 1x1 transparent GIF: the delayed image of the wrapper page.
_PIXEL = (
    b"GIF89a\x01\x00\x01\x00\x80\x00\x00\x00\x00\x00\xff\xff\xff!\xf9\x04\x01\x00\x00\x00\x00"
    b",\x00\x00\x00\x00\x01\x00\x01\x00\x00\x02\x02D\x01\x00;"
)


class ScreenshotError(RuntimeError):
    """Why no screenshot was written (one line)."""


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that is free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def find_chromium() -> str:
    """The Chromium executable on PATH (ScreenshotError naming the install command when there is none)."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    raise ScreenshotError("no Chromium found; fix: apt-get update && apt-get install -y chromium")


def viewer_url(web_port: int, grpc_port: int) -> str:
    """The web viewer's address, told to load from the gRPC server that holds the recording."""
    source = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
    return f"http://127.0.0.1:{web_port}/?url={source}"


def _wrapper_server(frame_url: str, wait_s: float) -> http.server.ThreadingHTTPServer:
    """Serves the wrapper page (the viewer in a full-window frame) and its image delayed by ``wait_s``."""
    page = (
        '<!doctype html><html><body style="margin:0;overflow:hidden">'
        f'<iframe src="{frame_url}" style="border:0;width:100vw;height:100vh"></iframe>'
        '<img src="/delay" alt="" style="display:none"></body></html>'
    ).encode()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            if self.path.startswith("/delay"):
                time.sleep(wait_s)
                body, kind = _PIXEL, "image/gif"
            else:
                body, kind = page, "text/html"
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: object) -> None:
            del format, args

    server = http.server.ThreadingHTTPServer(("127.0.0.1", free_tcp_port()), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def screenshot(
    recordings: Sequence[Path], out: Path, *, size: tuple[int, int] = (1600, 1000), wait_s: float = 90.0
) -> Path:
    """Render ``recordings`` (one flight's files, opened together) in the web viewer headless; write the PNG."""
    chromium = find_chromium()
    for recording in recordings:
        if not recording.is_file():
            raise ScreenshotError(f"{recording}: no such recording; fix: give a .rrd written by make run")
    web_port, grpc_port = free_tcp_port(), free_tcp_port()
    serve = [sys.executable, "-m", "rerun", "--serve-web", "--bind", "127.0.0.1"]
    serve += ["--web-viewer-port", str(web_port), "--port", str(grpc_port), *map(str, recordings)]
    quiet = subprocess.DEVNULL
    viewer = subprocess.Popen(serve, stdout=quiet, stderr=quiet, start_new_session=True)
    wrapper = _wrapper_server(viewer_url(web_port, grpc_port), wait_s)
    try:
        _wait_for_port(web_port, 30.0, viewer)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.unlink(missing_ok=True)
        shot = [
            chromium, "--headless=new", "--no-sandbox", "--hide-scrollbars", "--mute-audio",
            "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
            f"--window-size={size[0]},{size[1]}", f"--screenshot={out}",
            f"http://127.0.0.1:{wrapper.server_address[1]}/",
        ]  # fmt: skip
        subprocess.run(shot, capture_output=True, timeout=wait_s + 120.0, check=False, start_new_session=True)
    finally:
        wrapper.shutdown()
        wrapper.server_close()
        if viewer.poll() is None:  # the viewer and its children (the rerun binary)
            stop_group(viewer, 10.0)
    if not out.is_file() or out.stat().st_size == 0:
        raise ScreenshotError(f"Chromium wrote no screenshot at {out}")
    return out


def _wait_for_port(port: int, timeout_s: float, proc: subprocess.Popen[bytes]) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise ScreenshotError(f"rerun --serve-web exited with status {proc.returncode}")
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise ScreenshotError(f"the web viewer did not listen on 127.0.0.1:{port} within {timeout_s:g} s")


def fly(out_dir: Path) -> Path:
    """Fly the city-block delivery (obstacles, fence) and return its recording."""
    cmd = [sys.executable, "-m", "tools.run", "--mission", str(DEFAULT_MISSION), "--out-dir", str(out_dir)]
    proc = subprocess.run(cmd, cwd=REPO_ROOT, check=False)
    if proc.returncode != 0:
        raise ScreenshotError(f"the flight failed (tools.run exited {proc.returncode}); see {out_dir}")
    return out_dir / "flight.rrd"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.screenshot",
        description="Screenshot a flight recording in Rerun's web viewer, headless (Chromium, no GPU).",
    )
    parser.add_argument(
        "--recording",
        type=Path,
        nargs="+",
        default=None,
        help="one flight's .rrd file(s), e.g. a fleet's *.rrd (default: fly the city-block delivery)",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"PNG to write (default {DEFAULT_OUT})")
    parser.add_argument(
        "--wait-s",
        type=float,
        default=90.0,
        help="wall s the viewer gets to load and draw (default 90; more on a busy machine)",
    )
    args = parser.parse_args(argv)
    try:
        find_chromium()  # before a minute of flying
        with tempfile.TemporaryDirectory(prefix="quadsitl-shot-") as tmp:
            recordings = args.recording or [fly(Path(tmp) / "run")]
            written = screenshot(recordings, args.out, wait_s=args.wait_s)
    except ScreenshotError as exc:
        print(f"screenshot: {exc}", file=sys.stderr)
        return 2 if "no Chromium" in str(exc) else 1
    print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
