"""``tools.benchmarks --quick`` prints its smoke-check numbers and never overwrites the committed full results."""

from __future__ import annotations

import json
import types
from pathlib import Path

import pytest

from tools.benchmarks import BenchResult
from tools.benchmarks import __main__ as bench


@pytest.fixture
def one_fake_suite(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """A single suite returning one number; the working directory is a tmp dir holding a 'full' results file."""
    suite = types.SimpleNamespace(run=lambda quick: [BenchResult("fake_rtf", 2.5 if quick else 3.0)])
    monkeypatch.setattr(bench.importlib, "import_module", lambda name: suite)
    monkeypatch.chdir(tmp_path)
    full = tmp_path / "bench" / "results.json"
    full.parent.mkdir()
    full.write_text('{"fake_rtf": 3.0}\n')
    return full


def test_quick_only_prints(one_fake_suite: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert bench.main(["--quick", "--only", "fake"]) == 0
    out = capsys.readouterr().out
    assert "fake_rtf" in out and "2.5" in out and "not written" in out
    assert json.loads(one_fake_suite.read_text()) == {"fake_rtf": 3.0}


def test_quick_writes_only_where_asked(one_fake_suite: Path, tmp_path: Path) -> None:
    assert bench.main(["--quick", "--only", "fake", "--out", str(tmp_path / "q.json")]) == 0
    assert json.loads((tmp_path / "q.json").read_text())["fake_rtf"] == 2.5
    assert json.loads(one_fake_suite.read_text()) == {"fake_rtf": 3.0}


def test_quick_refuses_the_committed_file(one_fake_suite: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert bench.main(["--quick", "--only", "fake", "--out", "bench/results.json"]) == 2
    assert "bench/results.json" in capsys.readouterr().err
    assert json.loads(one_fake_suite.read_text()) == {"fake_rtf": 3.0}


def test_full_run_writes_the_committed_file(one_fake_suite: Path) -> None:
    assert bench.main(["--only", "fake"]) == 0
    assert json.loads(one_fake_suite.read_text())["fake_rtf"] == 3.0
    assert json.loads(one_fake_suite.read_text())["quick"] is False


def test_some_suites_into_the_committed_file_keep_the_other_suites_keys(
    one_fake_suite: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    one_fake_suite.write_text('{"fake_rtf": 1.0, "other_suite_key": 7.0}\n')
    assert bench.main(["--only", "fake"]) == 0
    assert json.loads(one_fake_suite.read_text())["other_suite_key"] == 7.0  # not dropped by a subset run
    assert json.loads(one_fake_suite.read_text())["fake_rtf"] == 3.0 and "merged into" in capsys.readouterr().out
    assert bench.main(["--only", "fake", "--replace"]) == 0
    assert "other_suite_key" not in json.loads(one_fake_suite.read_text())
    with pytest.raises(SystemExit):
        bench.main(["--only", "fake", "--merge", "--replace"])
