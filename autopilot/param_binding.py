"""Parameter changes take effect at once (in flight too): a table from parameter name to what it re-applies.

Each component's parameters are declared once in its ``param_decls`` (``autopilot.param_schema``); this module
only says which component re-reads which names. Reads the ``ParamStore``'s change notifications; calls the
bound handlers with ``(name, value)``; names bound to nothing change no state beyond the store.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from autopilot.control.param_decls import controller_param_specs
from autopilot.flight_control.controller import SETPOINT_PARAMS, FlightControl
from autopilot.mission.param_decls import mission_param_specs
from autopilot.navigation import Navigator
from autopilot.parameters.store import ParamStore
from autopilot.planner.param_decls import planner_param_specs
from autopilot.safety.failsafe import BatteryModel

Handler = Callable[[str, float], None]


class ParamBindings:
    """``name -> handlers``; subscribe it to a ``ParamStore`` (``ParamStore.subscribe``)."""

    def __init__(self) -> None:
        self._table: dict[str, list[Handler]] = {}
        self._every: list[Handler] = []

    def bind(self, names: Iterable[str], handler: Handler) -> None:
        """Call ``handler`` when any of ``names`` changes (in the order bound)."""
        for name in names:
            self._table.setdefault(name, []).append(handler)

    def bind_every(self, handler: Handler) -> None:
        """Call ``handler`` on every change, before the named handlers (cache invalidation)."""
        self._every.append(handler)

    def names(self) -> frozenset[str]:
        return frozenset(self._table)

    def __call__(self, name: str, value: float) -> None:
        for handler in self._every:
            handler(name, value)
        for handler in self._table.get(name, ()):
            handler(name, value)

    def attach(self, store: ParamStore) -> None:
        """Unknown names are refused at binding time: a typo cannot silently bind nothing."""
        unknown = sorted(name for name in self._table if name not in store)
        if unknown:
            raise ValueError(f"parameter bindings name undeclared parameters: {', '.join(unknown)}")
        store.subscribe(self)


def autopilot_bindings(
    nav: Navigator,
    control: FlightControl,
    battery: BatteryModel,
    on_controller_params: Handler,
    on_safety_radius: Handler,
) -> ParamBindings:
    """The autopilot's table: which component re-reads which parameter (attach it to the store)."""
    bindings = ParamBindings()
    bindings.bind_every(lambda _name, _value: nav.params_changed())  # cached mission targets are rebuilt
    bindings.bind(SETPOINT_PARAMS, lambda _n, _v: control.apply_setpoint_params())
    bindings.bind((s.name for s in controller_param_specs()), on_controller_params)
    bindings.bind(("PLD_MASS_KG",), lambda _n, _v: control.set_payload_released(control.payload_released))
    bindings.bind(("BAT_HOVER_ENDUR",), lambda _n, v: battery.set_hover_endurance_s(v))
    mission_names = [s.name for s in mission_param_specs()] + ["MIS_TAKEOFF_ALT"]
    bindings.bind(mission_names, lambda _n, _v: nav.apply_mission_params())
    bindings.bind([s.name for s in planner_param_specs()], lambda _n, _v: nav.apply_planner_params())
    bindings.bind(("GF_MAX_VER_DIST",), lambda _n, _v: nav.apply_altitude_limits())
    bindings.bind(("GF_MAX_HOR_DIST",), lambda _n, _v: nav.apply_upload_limits())  # the mission is re-checked
    bindings.bind(("CA_RSAFE_M",), on_safety_radius)  # drawn safety spheres follow R_safe
    return bindings
