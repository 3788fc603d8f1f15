"""Read a quadsitl ``.rrd`` back (rerun 0.41 ``rerun.chunk.RrdReader``): series, poses, text log.

Chunks of one entity are concatenated and sorted by ``sim_time``; values come back as
float64 arrays, times as integer microseconds of sim time.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader

from autopilot.telemetry import entities as ent


class RecordingReadError(ValueError):
    """The file is not a readable recording, or lacks what was asked for (the message says what)."""


@dataclass(frozen=True)
class Series:
    """One entity's column over sim time: ``t_us`` (n,), ``values`` (n, k)."""

    t_us: np.ndarray
    values: np.ndarray


@dataclass
class Recording:
    """Everything read from one recording, per entity path (without the leading ``/``)."""

    path: Path
    application_id: str
    recording_id: str
    blueprints: int
    # entity -> component ("Scalars:scalars") -> list of (t_us or None for static, arrow list array)
    _columns: dict[str, dict[str, list[tuple[np.ndarray | None, pa.Array]]]] = field(default_factory=dict)

    @property
    def entities(self) -> list[str]:
        return sorted(self._columns)

    def components(self, entity: str) -> list[str]:
        return sorted(self._columns.get(entity, {}))

    def _parts(self, entity: str, component: str) -> list[tuple[np.ndarray | None, pa.Array]]:
        parts = self._columns.get(entity, {}).get(component)
        if not parts:
            raise RecordingReadError(f"{self.path}: no {component} on entity {entity!r}")
        return parts

    def _timed(self, entity: str, component: str, width: int) -> Series:
        ts, vals = [], []
        for t_us, arr in self._parts(entity, component):
            if t_us is None:
                continue
            flat = arr.flatten()  # one instance per row
            if isinstance(flat.type, pa.FixedSizeListType):
                flat = flat.flatten()
            v = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=np.float64)
            if v.size != len(t_us) * width:
                raise RecordingReadError(f"{self.path}: {entity} {component} is not {width} values per row")
            ts.append(t_us)
            vals.append(v.reshape(len(t_us), width))
        if not ts:
            raise RecordingReadError(f"{self.path}: {entity} {component} has no rows on {ent.TIMELINE}")
        t = np.concatenate(ts)
        order = np.argsort(t, kind="stable")
        return Series(t[order], np.concatenate(vals)[order])

    def scalars(self, entity: str) -> Series:
        """A ``Scalars`` series: ``values`` (n, k) with k the number of lines."""
        parts = self._parts(entity, "Scalars:scalars")
        width = len(next(a for t, a in parts if t is not None)[0])
        return self._timed(entity, "Scalars:scalars", width)

    def translations(self, entity: str = ent.VEHICLE) -> Series:
        """``Transform3D`` translations (n, 3) (float32 in the file)."""
        return self._timed(entity, "Transform3D:translation", 3)

    def quaternions_wxyz(self, entity: str = ent.VEHICLE) -> Series:
        """``Transform3D`` rotations as ``q_ned_frd`` (n, 4), w first (the file stores x, y, z, w)."""
        s = self._timed(entity, "Transform3D:quaternion", 4)
        return Series(s.t_us, s.values[:, [3, 0, 1, 2]])

    def text_log(self, entity: str = ent.LOG) -> list[tuple[int, str, str]]:
        """``(t_us, level, text)`` of every TextLog row, in sim-time order."""
        rows: list[tuple[int, str, str]] = []
        texts = self._parts(entity, "TextLog:text")
        levels = self._columns[entity].get("TextLog:level", [])
        for k, (t_us, arr) in enumerate(texts):
            lv = levels[k][1].to_pylist() if k < len(levels) else [None] * len(arr)
            for j, text in enumerate(arr.to_pylist()):
                t = int(t_us[j]) if t_us is not None else -1
                rows.append((t, (lv[j] or [""])[0], (text or [""])[0]))
        rows.sort(key=lambda r: r[0])
        return rows

    def latest_component(self, entity: str, component: str) -> list[object]:
        """The value of a component at the latest sim time it was logged (static counts as latest)."""
        best: tuple[int, list[object]] | None = None
        for t_us, arr in self._parts(entity, component):
            if t_us is None:
                return arr.to_pylist()[-1]
            k = int(np.argmax(t_us))
            if best is None or t_us[k] >= best[0]:
                best = (int(t_us[k]), arr[k].as_py())
        assert best is not None
        return best[1]

    def rows(self, entity: str, component: str) -> list[tuple[int, list[object]]]:
        """``(t_us, instances)`` of every timed row of a component, in sim-time order (static rows left out)."""
        out: list[tuple[int, list[object]]] = []
        for t_us, arr in self._parts(entity, component):
            if t_us is not None:
                out += [(int(t), row) for t, row in zip(t_us, arr.to_pylist(), strict=True)]
        return sorted(out, key=lambda r: r[0])

    def static_component(self, entity: str, component: str) -> list[object]:
        """The latest static value of a component (a Python list of instances)."""
        for t_us, arr in reversed(self._parts(entity, component)):
            if t_us is None:
                return arr.to_pylist()[-1]
        raise RecordingReadError(f"{self.path}: {entity} {component} has no static value")


@dataclass(frozen=True, slots=True)
class BlueprintView:
    """One view of a saved layout: its title, origin (``/...``), kind (``Spatial3D``, ``TimeSeries`` ...) and
    contents queries (``$origin/**`` when not given)."""

    name: str
    origin: str
    kind: str
    contents: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Layout:
    """The layout (blueprint) a recording file carries: its application id, views and the names of its named
    containers (tabs), sorted."""

    application_id: str
    views: tuple[BlueprintView, ...]
    containers: tuple[str, ...]

    def view(self, name: str) -> BlueprintView:
        found = [v for v in self.views if v.name == name]
        if len(found) != 1:
            raise RecordingReadError(f"layout: {len(found)} views named {name!r}")
        return found[0]


def _one(fields: dict[str, list[object]], column: str) -> str:
    """The single value of a blueprint component ('' when absent)."""
    value = fields.get(column) or [""]
    return str(value[0])


def read_layout(path: str | Path) -> Layout:
    """The one blueprint saved in ``path``. Raises :class:`RecordingReadError` (none, several, unreadable)."""
    p = Path(path)
    try:
        reader = RrdReader(p)
        stores = reader.blueprints()
        if len(stores) != 1:
            raise RecordingReadError(f"{p}: {len(stores)} blueprints in the file, expected one")
        fields: dict[str, dict[str, list[object]]] = {}
        for chunk in reader.stream(store=stores[0]):
            batch = chunk.to_record_batch()
            mine = fields.setdefault(chunk.entity_path.removesuffix("/ViewContents"), {})
            for k, column in enumerate(batch.schema.names):
                if ":" in column:
                    mine[column] = batch.column(k).to_pylist()[-1] or []  # the latest row's instances
    except (OSError, ValueError, RuntimeError) as exc:
        if isinstance(exc, RecordingReadError):
            raise
        raise RecordingReadError(f"{p}: cannot read the layout ({exc})") from exc
    views = tuple(
        BlueprintView(
            _one(f, "ViewBlueprint:display_name"),
            _one(f, "ViewBlueprint:space_origin"),
            _one(f, "ViewBlueprint:class_identifier"),
            tuple(str(q) for q in f.get("ViewContents:query", ())),
        )
        for e, f in sorted(fields.items())
        if e.startswith("/view/") and "ViewBlueprint:class_identifier" in f
    )
    containers = tuple(
        sorted(
            _one(f, "ContainerBlueprint:display_name")
            for e, f in fields.items()
            if e.startswith("/container/") and f.get("ContainerBlueprint:display_name")
        )
    )
    return Layout(stores[0].application_id, views, containers)


def _t_us(column: pa.Array) -> np.ndarray:
    if not pa.types.is_duration(column.type):
        raise RecordingReadError(f"timeline {ent.TIMELINE} is not a duration")
    ns = column.cast(pa.int64()).to_numpy(zero_copy_only=False)
    return ns // 1000


def read_recording(path: str | Path, *, timeline: str = ent.TIMELINE) -> Recording:
    """Load every chunk of the first recording store in ``path``. Raises :class:`RecordingReadError`."""
    p = Path(path)
    if not p.is_file():
        raise RecordingReadError(f"{p}: no such recording")
    try:
        reader = RrdReader(p)
        stores = reader.recordings()
        if not stores:
            raise RecordingReadError(f"{p}: no recording store in the file")
        store = stores[0]
        out = Recording(p, store.application_id, store.recording_id, len(reader.blueprints()))
        chunks: Iterable = reader.stream(store=store)
        for chunk in chunks:
            batch = chunk.to_record_batch()
            entity = chunk.entity_path.lstrip("/")
            names = batch.schema.names
            t_us = _t_us(batch.column(names.index(timeline))) if timeline in names else None
            if t_us is None and not chunk.is_static:
                continue  # on other timelines only
            cols = out._columns.setdefault(entity, {})
            for name in names:
                if name == timeline or name.startswith("rerun.controls") or name in chunk.timeline_names:
                    continue
                cols.setdefault(name, []).append((t_us, batch.column(names.index(name))))
    except (OSError, ValueError, RuntimeError) as exc:
        if isinstance(exc, RecordingReadError):
            raise
        raise RecordingReadError(f"{p}: cannot read the recording ({exc})") from exc
    return out
