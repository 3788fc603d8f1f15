"""The space a search or an estimate explores: the campaign's searched ``vary`` inputs as a point with a known
density under the campaign's own draw (SPEC §14).

A ``uniform: [lo, hi]`` input is one continuous coordinate normalised to [0, 1] (nominal density 1); a
``choice`` input is one categorical coordinate, an index into its values (nominal mass 1/K: a case draws each
value equally often). A ``randint`` input (a seed) is never searched: every case draws it from its own stream, like
the simulator's seed, so it is the noise the search and the estimate average over. :func:`searched_case` turns a
point into case ``k`` of the campaign: the case's own draw with the searched inputs replaced, so its row and its
replay are an ordinary case's.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from typing import Any

from tools.campaign.cases import Case, draw
from tools.campaign.spec import CampaignSpec


@dataclass(frozen=True)
class Point:
    """One point of the space: continuous coordinates in [0, 1] and one value index per categorical input."""

    u: tuple[float, ...]
    cats: tuple[int, ...] = ()


@dataclass(frozen=True)
class SearchSpace:
    """The searched inputs: ``continuous`` (key, lo, hi) and ``categorical`` (key, values), in the file's order."""

    continuous: tuple[tuple[str, float, float], ...]
    categorical: tuple[tuple[str, tuple[Any, ...]], ...]

    @property
    def dims(self) -> int:
        return len(self.continuous)

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(len(values) for _, values in self.categorical)

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(k for k, *_ in self.continuous) + tuple(k for k, _ in self.categorical)

    def inputs(self, point: Point) -> dict[str, Any]:
        """The campaign inputs of ``point`` (continuous coordinates mapped onto their ranges)."""
        pairs = zip(self.continuous, point.u, strict=True)
        out: dict[str, Any] = {key: lo + (hi - lo) * float(u) for (key, lo, hi), u in pairs}
        out.update({key: values[c] for (key, values), c in zip(self.categorical, point.cats, strict=True)})
        return out

    def nominal_log_pdf(self) -> float:
        """log of the campaign's own density at any point of the space (uniform in [0, 1], 1/K per choice)."""
        return -sum(math.log(k) for k in self.sizes)


def space_of(spec: CampaignSpec, keys: tuple[str, ...]) -> SearchSpace:
    """The space of the ``vary`` entries named in ``keys`` (every ``uniform`` and ``choice`` one when empty)."""
    chosen = [(k, d) for k, d in spec.vary if (k in keys if keys else d.kind in ("uniform", "choice"))]
    continuous = tuple((k, float(d.args[0]), float(d.args[1])) for k, d in chosen if d.kind == "uniform")
    categorical = tuple((k, tuple(d.args)) for k, d in chosen if d.kind == "choice")
    return SearchSpace(continuous, categorical)


def searched_case(spec: CampaignSpec, space: SearchSpace, case_id: int, point: Point) -> Case:
    """Case ``case_id`` of ``spec`` (its seeds and unsearched inputs as drawn) with the point's inputs."""
    case = draw(spec, case_id)
    values = space.inputs(point)
    overrides = dict(case.overrides)
    for key, value in values.items():
        if key == "vehicle":
            case = replace(case, vehicle=str(value))
        elif key == "params":
            case = replace(case, params=str(value))
        elif key == "failures":
            case = replace(case, failures_json=json.dumps(value))
        else:
            overrides[key] = value
    return replace(case, overrides=tuple(overrides.items()))


def point_of_row(space: SearchSpace, row: dict[str, Any]) -> Point:
    """The point a results row was flown at (its searched inputs read back from its columns)."""
    u = []
    for key, lo, hi in space.continuous:
        value = float(row[f"vary.{key}"])
        u.append(0.0 if hi == lo else (value - lo) / (hi - lo))
    cats = []
    for key, values in space.categorical:
        column = key if key in ("vehicle", "params", "failures") else f"vary.{key}"
        text = row[column]
        stored = [v if isinstance(v, str) else json.dumps(v) for v in values]
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in values)
        cats.append([float(v) for v in values].index(float(text)) if numeric else stored.index(str(text)))
    return Point(tuple(u), tuple(cats))
