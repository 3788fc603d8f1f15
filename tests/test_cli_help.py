"""Every command's --help reads on its own: no references to files outside the repository ("SPEC §"),
no issue numbers, no RST backticks, a help line for every option; and every quadsitl command has --version."""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys

import pytest
from conftest import REPO_ROOT

#: (module, how its parser is found): build_parser() where there is one, else the parser main() builds.
COMMANDS = [
    "sim.cli",
    "autopilot.cli",
    "autopilot.launcher",
    "tools.gcs.cli",
    "tools.run.cli",
    "tools.benchmarks.__main__",
    "tools.rrd_figures",
    "tools.monitor",
    "tools.screenshot",
    "autopilot.param_schema",
    "tools.campaign.cli",
]


class _CapturedError(Exception):
    def __init__(self, parser: argparse.ArgumentParser) -> None:
        super().__init__("parser captured")
        self.parser = parser


def _parser(module_name: str, monkeypatch: pytest.MonkeyPatch) -> argparse.ArgumentParser:
    module = importlib.import_module(module_name)
    if hasattr(module, "build_parser"):
        return module.build_parser()

    def capture(self: argparse.ArgumentParser, *args: object, **kwargs: object) -> None:
        raise _CapturedError(self)

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
    with pytest.raises(_CapturedError) as caught:
        module.main([])
    return caught.value.parser


def _all_parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    found = [parser]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                found += _all_parsers(sub)
    return found


@pytest.mark.parametrize("module_name", COMMANDS)
def test_help_is_self_contained_and_complete(module_name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    for parser in _all_parsers(_parser(module_name, monkeypatch)):
        text = parser.format_help()
        for banned in ("SPEC", "issue ", "``", "../shared"):
            assert banned not in text, f"{parser.prog}: {banned!r} in its --help"
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction | argparse._HelpAction):
                continue
            assert action.help, f"{parser.prog}: {'/'.join(action.option_strings) or action.dest} has no help"


@pytest.mark.parametrize("command", [[], ["sim"], ["autopilot"], ["up"], ["campaign"]])
def test_every_quadsitl_command_has_a_version(command: list[str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "quadsitl_cli", *command, "--version"], cwd=REPO_ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("quadsitl") and "(Python 3." in proc.stdout


def test_up_defaults_to_real_time() -> None:
    from autopilot import launcher

    assert launcher.build_parser().parse_args([]).speed == "1"
