"""The numbers of the simulated traffic links (SPEC §13): the UTM service that relays the vehicles' own reports
and the ADS-B link of manned aircraft. ``TrafficLinkConfig`` is set by a world's ``traffic_link:`` mapping and
``quadsitl sim`` flags; ``sim.traffic`` flies it. Where each default comes from: docs/traffic.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

#: Default ADS-B reception range of the simulated receiver (m, 3D): far beyond any NMAC volume and a quad's horizon.
DEFAULT_TRAFFIC_RANGE_M = 10_000.0
#: NACp -> 95 % horizontal position error bound EPU (m) and vertical bound (m): RTCA DO-242A Table 3.2.11a (EPU);
#: vertical: DO-260A's VEPU for NACp 9-11 and DO-260B's GVA 1 (150 m) for NACp 8.
NACP_EPU_M = {8: 92.6, 9: 30.0, 10: 10.0, 11: 3.0}
NACP_VEPU_M = {8: 150.0, 9: 45.0, 10: 15.0, 11: 4.0}
#: NACv -> 95 % horizontal and vertical velocity error bounds (m/s): DO-242A Table 3.2.12a (10/3/1/0.3 m/s;
#: vertical 50/15/5/1.5 ft/s).
NACV_H_M_S = {1: 10.0, 2: 3.0, 3: 1.0, 4: 0.3}
NACV_V_M_S = {1: 15.24, 2: 4.572, 3: 1.524, 4: 0.4572}
#: 95 % radius of a circular 2D Gaussian in sigmas (sqrt(-2 ln 0.05)) and the 95 % two-sided 1D bound.
R95_2D_SIGMAS = math.sqrt(-2.0 * math.log(0.05))
R95_1D_SIGMAS = 1.959963984540054
_SEED_TAG_ERROR = 0xAD5B
_SEED_TAG_RECEPTION = 0x1090


@dataclass(frozen=True, slots=True)
class TrafficLinkConfig:
    """The receivers' link numbers (world key ``traffic_link:``, ``quadsitl sim --utm-*/--adsb-*``); sources of the
    defaults in docs/traffic.md."""

    #: UTM service: a report reaches the others this long after it was sent (ASTM F3411-22a network remote ID:
    #: NetSpDataResponseTime95thPercentile = 1 s).
    utm_latency_s: float = 1.0
    #: UTM service: a vehicle is relayed to receivers this close to its reported position (m, 3D; F3411-22a's
    #: largest display area, NetMaxDisplayAreaDiagonalKm = 7, seen from its centre).
    utm_range_m: float = 3_500.0
    #: ADS-B: navigation accuracy categories of every aircraft's broadcast (NACp 10: EPU < 10 m, VEPU < 15 m,
    #: NACv 2: < 3 m/s, 95 %; an SBAS (WAAS/EGNOS) position source, the usual ADS-B Out installation; 14 CFR
    #: 91.227 requires NACp >= 8, NACv >= 1; set 9 for an autonomous GNSS source).
    adsb_nacp: int = 10
    adsb_nacv: int = 2
    #: ADS-B: the broadcast position is this old when it arrives (14 CFR 91.227: uncompensated latency <= 0.6 s).
    adsb_latency_s: float = 0.6
    #: ADS-B: probability that a 1 Hz report reaches a receiver (two position squitters a second, at least one
    #: decoded; an assumption for short air-to-air ranges, docs/traffic.md).
    adsb_reception: float = 0.95
    #: ADS-B: correlation time of the navigation source's position error (s; GPS errors decorrelate over about a
    #: minute); 0: white.
    adsb_error_tau_s: float = 60.0
    #: ADS-B: reception range (m, 3D).
    adsb_range_m: float = DEFAULT_TRAFFIC_RANGE_M

    @classmethod
    def with_overrides(cls, *overrides: tuple[tuple[str, float], ...]) -> TrafficLinkConfig:
        """The defaults with ``(field, value)`` pairs applied in order (a world's ``traffic_link:``, then flags)."""
        fields: dict[str, float] = {}
        for pairs in overrides:
            fields.update(pairs)
        ints = {"adsb_nacp", "adsb_nacv"}
        return cls(**{k: (int(v) if k in ints else float(v)) for k, v in fields.items()})  # type: ignore[arg-type]

    def problem(self) -> str | None:
        """What is wrong with these numbers (one line), or None."""
        checks = (
            (0.0 <= self.utm_latency_s <= 60.0, f"utm_latency_s: expected 0..60 s, got {self.utm_latency_s}"),
            (self.utm_range_m > 0.0, f"utm_range_m: expected a positive distance, got {self.utm_range_m}"),
            (self.adsb_nacp in NACP_EPU_M, f"adsb_nacp: expected one of {sorted(NACP_EPU_M)}, got {self.adsb_nacp}"),
            (self.adsb_nacv in NACV_H_M_S, f"adsb_nacv: expected one of {sorted(NACV_H_M_S)}, got {self.adsb_nacv}"),
            (0.0 <= self.adsb_latency_s <= 10.0, f"adsb_latency_s: expected 0..10 s, got {self.adsb_latency_s}"),
            (0.0 < self.adsb_reception <= 1.0, f"adsb_reception: expected a probability in (0, 1], got "
             f"{self.adsb_reception}"),
            (0.0 <= self.adsb_error_tau_s <= 3600.0, f"adsb_error_tau_s: expected 0..3600 s, got "
             f"{self.adsb_error_tau_s}"),
            (self.adsb_range_m > 0.0, f"adsb_range_m: expected a positive distance, got {self.adsb_range_m}"),
        )  # fmt: skip
        return next((why for ok, why in checks if not ok), None)

    @property
    def adsb_sigmas(self) -> tuple[float, float, float, float]:
        """1-sigma errors (horizontal per axis m, vertical m, horizontal velocity per axis m/s, vertical m/s)."""
        return (
            NACP_EPU_M[self.adsb_nacp] / R95_2D_SIGMAS,
            NACP_VEPU_M[self.adsb_nacp] / R95_1D_SIGMAS,
            NACV_H_M_S[self.adsb_nacv] / R95_2D_SIGMAS,
            NACV_V_M_S[self.adsb_nacv] / R95_1D_SIGMAS,
        )


#: The keys of a world's ``traffic_link:`` mapping.
TRAFFIC_LINK_KEYS = frozenset(f.name for f in fields(TrafficLinkConfig))
