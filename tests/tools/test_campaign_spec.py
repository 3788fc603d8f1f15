"""Campaign files (tools.campaign.spec, .cases): FILE:LINE errors, seeding that depends only on the case id."""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_files import HOP, write_campaign

from tools.campaign.cases import draw, materialise
from tools.campaign.spec import CampaignFileError, PassRule, load_campaign


def _spec_file(tmp_path: Path, body: str) -> Path:
    (tmp_path / "hop.yaml").write_text(HOP)
    path = tmp_path / "c.yaml"
    path.write_text(body)
    return path


GOOD = "name: t\nbase: hop.yaml\ncases: 3\nseed: 1\n"


@pytest.mark.parametrize(
    ("body", "line", "words"),
    [
        (GOOD + "casess: 4\n", 5, ["casess: unknown key", "did you mean 'cases'?"]),
        (GOOD + "mode: sitll\n", 5, ["unknown mode 'sitll'", "did you mean 'sitl'?"]),
        ("name: t\nbase: nowhere.yaml\ncases: 3\nseed: 1\n", 2, ["no such file 'nowhere.yaml'"]),
        (GOOD + "vary:\n  world.wind.north_m_s: {uniform: [3, -3]}\n", 6, ["lo <= hi"]),
        (GOOD + "vary:\n  world.wind.nort_m_s: {uniform: [-3, 3]}\n", 6, ["nort_m_s", "unknown field"]),
        (GOOD + "vary:\n  world.payload_kg: {gauss: [0, 1]}\n", 6, ["unknown distribution 'gauss'"]),
        (GOOD + "vary:\n  vehicle: {choice: [x500, x900]}\n", 6, ["unknown name 'x900'"]),
        (GOOD + "vary:\n  params: {choice: [default, no_such_gains.yaml]}\n", 6, ["no such file 'no_such_gains.yaml'"]),
        (GOOD + "vary:\n  failures: {choice: [[{at_s: 4, inject: gps_of}]]}\n", 6, ["unknown failure 'gps_of'"]),
        (GOOD + "vary:\n  failures: {choice: [[{at_s: 4, inject: gps_off, motor: 2}]]}\n", 6, ["only motor_off"]),
        (GOOD + "vary:\n  wind: {uniform: [0, 1]}\n", 6, ["unknown input", "dotted path"]),
        (GOOD + "pass_if: {landed: yes-ish}\n", 5, ["expected true or false"]),
        (GOOD + "pass_if:\n  colisions: 0\n", 6, ["unknown column", "did you mean 'collisions'?"]),
        (GOOD + "sim_time_s: -4\n", 5, ["expected a number >= 1"]),
        ("name: t\nbase: hop.yaml\ncases: 0\nseed: 1\n", 3, ["expected an integer >= 1"]),
        ("name: t\nbase: [hop.yaml, 7]\ncases: 1\nseed: 1\n", 2, ["expected a mission file path"]),
        ("name: t\n  base: : x\n", 2, [""]),
    ],
)
def test_errors_name_file_line_and_fix(tmp_path: Path, body: str, line: int, words: list[str]) -> None:
    path = _spec_file(tmp_path, body)
    with pytest.raises(CampaignFileError) as err:
        load_campaign(path)
    message = str(err.value)
    assert message.startswith(f"{path}:{line}"), message
    assert "\n" not in message
    for word in words:
        assert word in message


def test_case_inputs_depend_only_on_case_id_and_seed(tmp_path: Path) -> None:
    spec = load_campaign(write_campaign(tmp_path, cases=40))
    forward = [draw(spec, k) for k in range(40)]
    backward = [draw(spec, k) for k in reversed(range(40))][::-1]
    assert forward == backward  # the order cases are drawn (or run) in changes nothing
    bigger = load_campaign(write_campaign(tmp_path / "b", cases=1000))
    assert draw(bigger, 17).overrides == forward[17].overrides  # nor does the campaign's size
    assert draw(bigger, 17).sim_seed == forward[17].sim_seed
    assert len({c.sim_seed for c in forward}) == 40  # each case its own simulator seed
    winds = [c.overrides[0][1] for c in forward]
    assert all(-2.0 <= w <= 2.0 for w in winds) and len(set(winds)) == 40
    assert {c.failures_json for c in forward} == {"[]", '[{"at_s": 12, "inject": "motor_off", "motor": 2}]'}
    assert materialise(spec, forward[5]) == materialise(spec, draw(spec, 5))


def test_materialised_files_carry_the_drawn_values(tmp_path: Path) -> None:
    import yaml

    spec = load_campaign(write_campaign(tmp_path))
    case = next(draw(spec, k) for k in range(10) if draw(spec, k).failures)
    files = materialise(spec, case)
    world = yaml.safe_load(files.world_yaml)
    assert world["world"]["wind"]["north_m_s"] == case.overrides[0][1]  # bit for bit through YAML
    assert world["vehicle"] == "x500"
    assert world["world"]["failures"] == [{"at_s": 12, "inject": "motor_off", "motor": 2}]  # the world file's key
    script = yaml.safe_load(files.script_yaml)
    assert script == [{"at_s": 3.0, "cmd": "arm"}, {"at_s": 3.5, "cmd": "mission_start"}]
    assert yaml.safe_load(files.params_yaml) == {}  # the autopilot enables injection for a world with failures


def test_pass_rules() -> None:
    assert PassRule("landed", equals=True).failure(False) == "landed False != True"
    assert PassRule("landed", equals=True).failure(True) is None
    assert PassRule("collisions", max=0).failure(1) == "collisions 1 > 0"
    assert PassRule("min_clearance_m", min=0.5).failure(0.2) == "min_clearance_m 0.2 < 0.5"
    assert PassRule("min_clearance_m", min=0.5).failure(float("nan")) == "min_clearance_m unknown"
    assert PassRule("tracking_pos_rms_m", max=1.0).failure(float("nan")) is None


def test_shipped_campaigns_load() -> None:
    root = Path(__file__).resolve().parents[2]
    files = sorted((root / "missions" / "campaigns").glob("*.yaml"))
    assert len(files) >= 2
    for path in files:
        spec = load_campaign(path)
        assert spec.cases >= 100
        draw(spec, 0)
