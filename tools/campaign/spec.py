"""The campaign file (``quadsitl campaign FILE.yaml``): schema, validation with FILE:LINE errors (SPEC §14).

::

    name: delivery-wind-sweep
    base: missions/delivery.yaml          # a mission/world file, or a list of them (one is drawn per case)
    cases: 1000
    seed: 7                               # case k draws from numpy default_rng([k, seed])
    mode: inproc                          # inproc (default): one process, the same truth hash; sitl: processes
    vary:                                 # dotted paths into the base file, or vehicle / params / failures
      world.wind.north_m_s: {uniform: [-6, 6]}
      world.payload_kg: {choice: [0.0, 0.5, 1.0]}
      vehicle: {choice: [x500, delivery650]}
      params: {choice: [default, results/paper/gains_pid.yaml]}
      failures: {choice: [[], [{at_s: 40, inject: gps_off}]]}
    pass_if: {landed: true, collisions: 0, fence_breaches: 0, items_missed: 0}
    sim_time_s: 160                       # every flight runs exactly this much sim time (the truth hash's span)
    deadline_s: 300                       # wall seconds per case before it is a timeout row
    arm_at_s: 3.0                         # scripted arm; mission_start 0.5 s later
    estimator: ekf

Relative paths (base, params files) are resolved against the current directory, then the campaign file's folder.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mavlink_bridge.contract.source_lines import YamlSource, YamlSyntaxError, did_you_mean, read_yaml
from tools.campaign.inputs import (
    CaseInputError,
    check_failures,
    check_params,
    check_vehicle,
    resolve_path,
    with_override,
)
from tools.campaign.search_config import EstimateConfig, SearchConfig, parse_estimate, parse_search

MODES = ("sitl", "inproc")
#: The default mode: every shipped single-vehicle campaign flies to the same truth hash in both modes
#: (``tests/tools/test_campaign_modes_agree.py``), and a fleet flies bit for bit only in process.
DEFAULT_MODE = "inproc"
#: The ``base`` of an encounter campaign's cases (their fleet worlds are generated, not read from a file).
ENCOUNTER_BASE = "encounter"
RUN_KEYS = ("vehicle", "params", "failures")
DISTRIBUTIONS = ("uniform", "choice", "randint")
#: Row columns ``pass_if`` may test: booleans compare equal, numbers are an upper bound unless ``{min: x}``.
PASS_KEYS = {
    "landed": bool,
    "disarmed": bool,
    "collisions": int,
    "fence_breaches": int,
    "items_missed": int,
    "items_bypassed": int,
    "failsafes": int,
    "min_clearance_m": float,
    "tracking_pos_rms_m": float,
    "tracking_pos_max_m": float,
    "max_tilt_deg": float,
    "energy_used_frac": float,
    "traffic_contacts": float,  # fleet cases (tools.campaign.fleet_record)
    "traffic_nmac": float,
    "traffic_min_sep_m": float,
    "traffic_volume_entries": float,
    "traffic_min_dist_m": float,
    "traffic_completion": float,
}
DEFAULT_PASS_IF = {"landed": True, "collisions": 0}
_TOP_KEYS = (
    "name",
    "base",
    "cases",
    "seed",
    "mode",
    "vary",
    "pass_if",
    "sim_time_s",
    "deadline_s",
    "arm_at_s",
    "estimator",
    "encounter",
    "search",
    "estimate",
)
#: ``encounter:`` keys (tools.encounters.encounter_world's arguments; each drawn from the case's seed when absent).
ENCOUNTER_KEYS = ("kind", "vehicles", "manned")


class CampaignFileError(ValueError):
    """A campaign file that cannot run; the message starts with FILE:LINE and ends with the fix."""


@dataclass(frozen=True)
class Distribution:
    """How one varied input is drawn: ``uniform`` [lo, hi), ``randint`` [lo, hi] or a ``choice`` among values."""

    kind: str
    args: tuple[Any, ...]


@dataclass(frozen=True)
class PassRule:
    """One ``pass_if`` entry: the column must equal ``equals``, or lie within [``min``, ``max``]."""

    column: str
    equals: bool | None = None
    min: float | None = None
    max: float | None = None

    def failure(self, value: Any) -> str | None:
        """Why ``value`` fails this rule (None: it passes)."""
        if value is None or (isinstance(value, float) and math.isnan(value)):
            return None if self.equals is None and self.min is None else f"{self.column} unknown"
        if self.equals is not None and bool(value) is not self.equals:
            return f"{self.column} {value} != {self.equals}"
        if self.max is not None and value > self.max:
            return f"{self.column} {value:g} > {self.max:g}"
        if self.min is not None and value < self.min:
            return f"{self.column} {value:g} < {self.min:g}"
        return None


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign file; ``vary`` keeps the file's order (the order cases draw in)."""

    path: str
    name: str
    bases: tuple[str, ...]
    cases: int
    seed: int
    mode: str
    vary: tuple[tuple[str, Distribution], ...]
    pass_if: tuple[PassRule, ...]
    sim_time_s: float
    deadline_s: float
    arm_at_s: float
    estimator: str
    text: str  # the file as written (kept in the results' metadata)
    encounter: tuple[tuple[str, Any], ...] | None = None  # fleet encounters generated per case (docs/traffic.md)
    search: SearchConfig | None = None  # quadsitl campaign search / estimate (tools.campaign.search_config)
    estimate: EstimateConfig | None = None  # estimate: (its defaults when absent)


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign file (:class:`CampaignFileError` naming FILE:LINE and the fix)."""
    p = Path(path)
    try:
        src = read_yaml(p)
    except OSError as exc:
        raise CampaignFileError(f"{p}: cannot read: {exc.strerror}; fix: check the campaign file's path") from None
    except YamlSyntaxError as exc:
        raise CampaignFileError(str(exc)) from None
    return _Checker(src, p).spec()


def pass_rules_of(campaign_text: str, path: str | Path) -> tuple[PassRule, ...]:
    """The ``pass_if`` rules of a campaign file's text (a results folder's copy: replay judges with them)."""
    from mavlink_bridge.contract.source_lines import parse_yaml

    src = parse_yaml(campaign_text, path)
    raw = src.data.get("pass_if", DEFAULT_PASS_IF) if isinstance(src.data, dict) else DEFAULT_PASS_IF
    return tuple(_Checker(src, Path(path)).pass_if(raw))


class _Checker:
    def __init__(self, src: YamlSource, path: Path) -> None:
        self.src, self.path = src, path

    def fail(self, node: tuple[str | int, ...], message: str, fix: str) -> CampaignFileError:
        return CampaignFileError(
            f"{self.src.where(*node)}: {'.'.join(map(str, node)) or 'file'}: {message}; fix: {fix}"
        )

    def spec(self) -> CampaignSpec:
        doc = self.src.data
        if not isinstance(doc, dict):
            raise self.fail(
                (), "expected a mapping of campaign keys", f"start with 'name:'; keys {', '.join(_TOP_KEYS)}"
            )
        for key in doc:
            if key not in _TOP_KEYS:
                raise self.fail((str(key),), "unknown key", did_you_mean(key, _TOP_KEYS))
        encounter = self.encounter(doc) if "encounter" in doc else None
        for key in ("name", "cases", "seed") if encounter is not None else ("name", "base", "cases", "seed"):
            if key not in doc:
                raise self.fail((), f"missing '{key}'", f"add '{key}:' (see docs/campaigns.md)")
        name = doc["name"]
        if not isinstance(name, str) or not name.strip():
            raise self.fail(("name",), f"expected a non-empty name, got {name!r}", "name: my-campaign")
        mode = doc.get("mode", DEFAULT_MODE)
        if mode not in MODES:
            raise self.fail(("mode",), f"unknown mode {mode!r}", did_you_mean(mode, MODES))
        estimator = doc.get("estimator", "ekf")
        from autopilot.estimation import ESTIMATORS

        if estimator not in ESTIMATORS:
            raise self.fail(("estimator",), f"unknown estimator {estimator!r}", did_you_mean(estimator, ESTIMATORS))
        bases = self.bases(doc["base"]) if encounter is None else (ENCOUNTER_BASE,)
        vary = tuple(self.vary(doc.get("vary") or {}, bases))
        if encounter is not None and any(key != "params" for key, _ in vary):
            raise self.fail(("vary",), "an encounter campaign varies only params", "vary: {params: {choice: [...]}}")
        return CampaignSpec(
            path=str(self.path),
            name=name,
            bases=bases,
            cases=self.integer(doc, "cases", 1),
            seed=self.integer(doc, "seed", 0),
            mode=mode,
            vary=vary,
            pass_if=tuple(self.pass_if(doc.get("pass_if", DEFAULT_PASS_IF))),
            sim_time_s=self.number(doc, "sim_time_s", 200.0, 1.0),
            deadline_s=self.number(doc, "deadline_s", 300.0, 0.1),
            arm_at_s=self.number(doc, "arm_at_s", 3.0, 0.0),
            estimator=estimator,
            text=self.path.read_text(),
            encounter=encounter,
            search=parse_search(doc["search"], vary, self.fail) if "search" in doc else None,
            estimate=parse_estimate(doc.get("estimate"), self.fail) if "estimate" in doc else None,
        )

    def encounter(self, doc: dict) -> tuple[tuple[str, Any], ...]:
        """``encounter: {kind: K, vehicles: N, manned: B}`` (each optional: drawn per case from its seed)."""
        from tools.encounters import KINDS, MIN_VEHICLES

        raw = doc["encounter"]
        if "base" in doc:
            raise self.fail(("base",), "an encounter campaign generates its worlds", "remove base: (or encounter:)")
        if raw is None:
            raw = {}
        if not isinstance(raw, dict):
            raise self.fail(("encounter",), f"expected a mapping, got {raw!r}", "encounter: {} (all drawn)")
        for key, value in raw.items():
            node = ("encounter", str(key))
            if key not in ENCOUNTER_KEYS:
                raise self.fail(node, "unknown key", did_you_mean(key, ENCOUNTER_KEYS))
            ok = {
                "kind": value in KINDS,
                "vehicles": isinstance(value, int) and not isinstance(value, bool) and 2 <= value <= 8,
                "manned": isinstance(value, bool),
            }[key]
            if not ok:
                fix = {"kind": f"one of {', '.join(KINDS)}", "vehicles": "2 to 8", "manned": "true or false"}[key]
                raise self.fail(node, f"bad value {value!r}", fix)
        low = MIN_VEHICLES.get(raw.get("kind", ""), 2)
        if raw.get("vehicles", 8) < low:
            raise self.fail(
                ("encounter", "vehicles"), f"a {raw['kind']} encounter has {low} to 8 vehicles", f"{low} to 8"
            )
        return tuple(sorted(raw.items()))

    def integer(self, doc: dict, key: str, low: int) -> int:
        value = doc[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise self.fail((key,), f"expected an integer >= {low}, got {value!r}", f"{key}: {max(low, 1)}")
        return value

    def number(self, doc: dict, key: str, default: float, low: float) -> float:
        value = doc.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < low:
            raise self.fail((key,), f"expected a number >= {low:g}, got {value!r}", f"{key}: {default:g}")
        return float(value)

    def bases(self, raw: Any) -> tuple[str, ...]:
        entries = raw if isinstance(raw, list) else [raw]
        node_of = (lambda i: ("base", i)) if isinstance(raw, list) else (lambda i: ("base",))
        if not entries:
            raise self.fail(("base",), "empty list", "name at least one mission file")
        out = []
        for i, entry in enumerate(entries):
            if not isinstance(entry, str):
                raise self.fail(
                    node_of(i), f"expected a mission file path, got {entry!r}", "base: missions/delivery.yaml"
                )
            found = resolve_path(entry, self.path)
            if found is None:
                raise self.fail(
                    node_of(i), f"no such file {entry!r}", "give a path from here or from the campaign file"
                )
            problem = check_world_doc(found, None)
            if problem:
                raise self.fail(node_of(i), f"{entry}: {problem}", "fix the mission file")
            out.append(str(found))
        return tuple(out)

    def vary(self, raw: Any, bases: tuple[str, ...]) -> list[tuple[str, Distribution]]:
        if not isinstance(raw, dict):
            raise self.fail(("vary",), "expected a mapping of input: distribution", "vary: {world.payload_kg: ...}")
        out = []
        for key, dist_raw in raw.items():
            key = str(key)
            node = ("vary", key)
            if key not in RUN_KEYS and not key.startswith("world.") and "." not in key:
                raise self.fail(
                    node,
                    "unknown input",
                    f"a dotted path into the base file (world.wind.north_m_s) or {did_you_mean(key, RUN_KEYS)}",
                )
            dist = self.distribution(node, dist_raw)
            values = list(dist.args) if dist.kind == "choice" else [dist.args[0], dist.args[1]]
            for value in values:
                self.check_value(node, key, value, bases)
            out.append((key, dist))
        return out

    def distribution(self, node: tuple[str, ...], raw: Any) -> Distribution:
        fix = "{uniform: [lo, hi]}, {randint: [lo, hi]} or {choice: [a, b, ...]}"
        if not isinstance(raw, dict) or len(raw) != 1:
            raise self.fail(node, f"expected one distribution, got {raw!r}", fix)
        ((kind, args),) = raw.items()
        if kind not in DISTRIBUTIONS:
            raise self.fail((*node, kind), f"unknown distribution {kind!r}", did_you_mean(kind, DISTRIBUTIONS))
        if not isinstance(args, list) or not args:
            raise self.fail((*node, kind), f"expected a non-empty list, got {args!r}", fix)
        if kind in ("uniform", "randint"):
            numeric = all(isinstance(a, int | float) and not isinstance(a, bool) and math.isfinite(a) for a in args)
            if len(args) != 2 or not numeric or args[0] > args[1]:
                raise self.fail((*node, kind), f"expected [lo, hi] numbers with lo <= hi, got {args!r}", fix)
            if kind == "randint" and not all(isinstance(a, int) for a in args):
                raise self.fail((*node, kind), f"expected integers, got {args!r}", "randint: [0, 1000]")
        return Distribution(kind, tuple(args))

    def check_value(self, node: tuple[str, ...], key: str, value: Any, bases: tuple[str, ...]) -> None:
        """One value a case may draw, checked as the flight will use it."""
        try:
            if key == "vehicle":
                check_vehicle(value)
            elif key == "params":
                check_params(value, self.path)
            elif key == "failures":
                check_failures(value)
            else:
                for base in bases:
                    problem = check_world_doc(Path(base), with_override(Path(base), key, value))
                    if problem:
                        raise CaseInputError(f"{key} = {value!r} in {base}: {problem}")
        except CaseInputError as exc:
            raise self.fail(node, str(exc), "pick values the world, vehicle and autopilot accept") from None

    def pass_if(self, raw: Any) -> list[PassRule]:
        if not isinstance(raw, dict):
            raise self.fail(("pass_if",), "expected a mapping", "pass_if: {landed: true, collisions: 0}")
        rules = []
        for key, value in raw.items():
            node = ("pass_if", str(key))
            kind = PASS_KEYS.get(str(key))
            if kind is None:
                raise self.fail(node, "unknown column", did_you_mean(key, PASS_KEYS))
            if kind is bool:
                if not isinstance(value, bool):
                    raise self.fail(node, f"expected true or false, got {value!r}", f"{key}: true")
                rules.append(PassRule(str(key), equals=value))
            elif isinstance(value, dict) and set(value) <= {"min", "max"} and value:
                if not all(_is_num(v) for v in value.values()):
                    raise self.fail(node, f"expected numbers, got {value!r}", f"{key}: {{min: 0.5}}")
                rules.append(PassRule(str(key), min=value.get("min"), max=value.get("max")))
            elif _is_num(value):
                rules.append(PassRule(str(key), max=float(value)))
            else:
                raise self.fail(node, f"expected an upper bound or {{min: x, max: y}}, got {value!r}", f"{key}: 0")
        return rules


def _is_num(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def check_world_doc(path: Path, doc: dict | None) -> str | None:
    """What the simulator and the mission loader refuse in this mission (``doc``: an edited copy), or None."""
    import tempfile

    import yaml

    from autopilot.mission.files import MissionFileError, load_mission_file
    from sim.world import WorldConfigError, load_world

    try:
        if doc is None:
            load_world(path)
            load_mission_file(path)
            return None
        load_world(doc)
        with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=True) as tmp:
            tmp.write(yaml.safe_dump(doc, sort_keys=False))
            tmp.flush()
            load_mission_file(tmp.name)
    except (WorldConfigError, MissionFileError) as exc:
        return str(exc).replace(tempfile.gettempdir(), "").split(": ", 1)[-1] if doc is not None else str(exc)
    return None
