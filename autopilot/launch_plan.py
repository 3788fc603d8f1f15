"""Which ports each vehicle of ``quadsitl up`` listens on and sends to: PX4's multi-vehicle SITL conventions.

Vehicle i of block N (``--instance N``), host 127.0.0.1 unless ``--listen`` says otherwise:

=========  =====================================  ================================================
link       vehicle i listens on                   sends to
=========  =====================================  ================================================
sim        14560+N+i (the simulator)              (the autopilot sends there)
GCS        18570+N+i                              14550+N, the same for every vehicle (one GCS sees
                                                  the fleet by system id); ``--gcs-target`` moves it
API        14580+N+i                              14540+N+min(i, 9) (PX4 pins i > 9 to 14549)
=========  =====================================  ================================================

and MAV_SYS_ID i+1. A world without ``vehicles:`` is a fleet of one unnamed vehicle, instance 0 of the table:
its autopilot gets ``--instance N`` and only the link URLs typed (each used as typed, every other default shifted
by the autopilot itself). A fleet world's vehicles get every URL from the table, so per-vehicle ``--sim``,
``--gcs``, ``--api`` and ``--api-target`` are refused there (``--gcs off``, ``--api off``, ``--listen`` and
``--gcs-target`` are taken). Vehicles 20 and beyond would listen for the simulator where vehicles 0.. listen for
their API, so a fleet of more than 20 vehicles needs ``--api off``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from autopilot.cli import link_urls
from mavlink_bridge.lockstep import DEFAULT_LISTEN_URL
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, resolve_url

SIM_PORT = 14560
GCS_LOCAL_PORT = 18570
GCS_PORT = 14550
API_LOCAL_PORT = 14580
API_PORT = 14540
#: PX4: the API link's remote port stops at 14540 + 9 (14549), below the GCS port.
API_PORT_LAST_OFFSET = 9
#: API local ports (14580+i) meet the simulator's (14560+j) at j = i + 20.
MAX_VEHICLES_WITH_API = 20
#: The airframe when neither ``--vehicle`` nor the world names one.
DEFAULT_AIRFRAME = "x500"


@dataclass(frozen=True, slots=True)
class VehicleLinks:
    """One vehicle's autopilot: its name, airframe and link URLs (None: the autopilot's default for ``instance``)."""

    index: int
    name: str | None  # None: the one vehicle of a world without vehicles: (no entry, directory or recording of its own)
    airframe: str
    instance: int
    sim: str | None
    gcs: str | None
    gcs_target: str | None
    api: str | None
    api_target: str | None
    home_ne_m: tuple[float, float] | None = None  # about the world's home; None: given as lat_deg/lon_deg

    @property
    def sys_id(self) -> int:
        return self.index + 1

    def urls(self) -> dict[str, str]:
        """Every link's URL as the autopilot will use it (defaults resolved; ``off`` stays ``off``)."""
        fields = ("instance", "sim", "gcs", "gcs_target", "api", "api_target")
        return link_urls(argparse.Namespace(**{f: getattr(self, f) for f in fields}))


@dataclass(frozen=True, slots=True)
class LaunchPlan:
    """The simulator's lockstep address (vehicle i: its port + i) and every vehicle's links."""

    listen: LinkUrl
    vehicles: tuple[VehicleLinks, ...]

    @property
    def fleet(self) -> bool:
        """A world with ``vehicles:`` (named vehicles), not a world flown by one unnamed vehicle."""
        return self.vehicles[0].name is not None

    def sim_listen(self, vehicle: VehicleLinks) -> str:
        """Where the simulator listens for ``vehicle``'s lockstep datagrams."""
        return f"udpin:{self.listen.host}:{self.listen.port + vehicle.index}"

    def listen_urls(self) -> list[str]:
        """Every link address of the run (the simulator's, each autopilot's GCS and API): the listening ones are
        checked free before anything starts."""
        return [url for v in self.vehicles for url in (self.sim_listen(v), v.urls()["gcs"], v.urls()["api"])]


def fleet_entries(world: str | None) -> list[dict[str, Any]]:
    """The ``vehicles:`` entries of a world file (empty: not a fleet world, or unreadable: the checks say why)."""
    data = _world_yaml(world)
    entries = data.get("vehicles") if isinstance(data, dict) else None
    return [e for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []


def world_vehicle(world: str | None) -> str | None:
    """The ``vehicle:`` of a mission or world YAML (the default airframe of ``up``), if any."""
    data = _world_yaml(world)
    vehicle = data.get("vehicle") if isinstance(data, dict) else None
    return str(vehicle) if vehicle else None


def _world_yaml(world: str | None) -> object:
    if world is None or not world.endswith((".yaml", ".yml")):
        return None
    try:
        return yaml.safe_load(Path(world).read_text())
    except (OSError, yaml.YAMLError):
        return None


def home_offset_ne_m(entry: dict[str, Any]) -> tuple[float, float] | None:
    """A ``vehicles:`` entry's ``home: {north_m, east_m}`` about the world's home (None: given otherwise)."""
    home = entry.get("home")
    if not isinstance(home, dict) or not ({"north_m", "east_m"} & set(home)):
        return None
    try:
        return float(home.get("north_m", 0.0)), float(home.get("east_m", 0.0))
    except (TypeError, ValueError):
        return None  # the simulator's check refuses the file and says why


def plan_launch(args: argparse.Namespace) -> LaunchPlan:
    """Every vehicle's links for parsed ``up`` options (LinkUrlError for a bad URL or one a fleet cannot take)."""
    listen = LinkUrl.parse(resolve_url(args.listen, DEFAULT_LISTEN_URL, args.instance))
    if listen.mode is not LinkMode.LISTEN:
        raise LinkUrlError(f"--listen must be udp:HOST:PORT or udpin:HOST:PORT, got {args.listen!r}")
    airframe = args.vehicle or world_vehicle(args.world) or DEFAULT_AIRFRAME
    entries = fleet_entries(args.world)
    if entries:
        return LaunchPlan(listen, _fleet_links(args, entries, airframe, listen))
    link_urls(args)  # LinkUrlError for a malformed link URL before anything starts
    sim = args.sim or (f"udpout:{listen.host}:{listen.port}" if args.listen is not None else None)
    one = VehicleLinks(
        index=0,
        name=None,
        airframe=airframe,
        instance=args.instance,
        sim=sim,
        gcs=args.gcs,
        gcs_target=args.gcs_target,
        api=args.api,
        api_target=args.api_target,
    )
    return LaunchPlan(listen, (one,))


def _fleet_links(
    args: argparse.Namespace, entries: list[dict[str, Any]], airframe: str, listen: LinkUrl
) -> tuple[VehicleLinks, ...]:
    """The table above for each ``vehicles:`` entry; every port checked to be planned once."""
    for option in ("sim", "api_target"):
        if getattr(args, option) is not None:
            raise LinkUrlError(
                f"--{option.replace('_', '-')}: a fleet world gives each vehicle its own; use --instance N"
            )
    for option in ("gcs", "api"):
        value = getattr(args, option)
        if value is not None and value != "off":
            raise LinkUrlError(f"--{option}: a fleet world gives each vehicle its own ({option} off is allowed)")
    n, block, host = len(entries), args.instance, listen.host
    gcs_port = GCS_PORT + block if args.gcs_target is None else LinkUrl.parse(args.gcs_target).port
    api_on = args.api != "off"
    if api_on and n > MAX_VEHICLES_WITH_API:
        raise LinkUrlError(
            f"{n} vehicles: the API links of vehicles 0..{n - MAX_VEHICLES_WITH_API - 1} would take the simulator "
            f"ports of vehicles {MAX_VEHICLES_WITH_API}..{n - 1}; fix: --api off"
        )
    gcs_local = [None if args.gcs == "off" else GCS_LOCAL_PORT + block + i for i in range(n)]
    api_local = [API_LOCAL_PORT + block + i if api_on else None for i in range(n)]
    bound = [p for i in range(n) for p in (listen.port + i, gcs_local[i], api_local[i]) if p is not None]
    bound += [gcs_port] if args.gcs_target is None else []  # the GCS's own port must stay free for the GCS
    taken = sorted({p for p in bound if bound.count(p) > 1})
    if taken:
        raise LinkUrlError(f"ports {taken} would be used twice by this fleet; fix: another --instance or --listen port")
    return tuple(
        VehicleLinks(
            index=i,
            name=str(e.get("name", f"vehicle{i}")),
            airframe=str(e.get("vehicle") or airframe),
            instance=0,
            sim=f"udpout:{host}:{listen.port + i}",
            gcs="off" if gcs_local[i] is None else f"udpin:{host}:{gcs_local[i]}",
            gcs_target=args.gcs_target or f"udpout:{host}:{gcs_port}",
            api="off" if api_local[i] is None else f"udpin:{host}:{api_local[i]}",
            api_target=f"udpout:{host}:{API_PORT + block + min(i, API_PORT_LAST_OFFSET)}",
            home_ne_m=home_offset_ne_m(e),
        )
        for i, e in enumerate(entries)
    )
