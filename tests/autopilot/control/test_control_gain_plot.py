"""The k(s) comparison figure (SPEC §6.1: show raised cosine vs paper literal in a plot) is written."""

from __future__ import annotations

from pathlib import Path

from autopilot.control.param_decls import DEFAULT_GAINS_PATH
from tools.research.plot_gain_schedule import main


def test_gain_schedule_plot_is_written(tmp_path: Path) -> None:
    out = tmp_path / "k.png"
    assert main(["--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000


def test_gain_set_plot_of_the_shipped_gains_is_written(tmp_path: Path) -> None:
    out = tmp_path / "gains.png"
    assert main(["--gains", str(DEFAULT_GAINS_PATH), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    bad = tmp_path / "bad.yaml"
    bad.write_text("format: nope\n")
    assert main(["--gains", str(bad), "--out", str(tmp_path / "x.png")]) == 2
