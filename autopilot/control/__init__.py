"""The paper's controller (SPEC §6): variable gains, NLVG-PID terms, the cascade and the quad-X mixer."""

from autopilot.control.airframe import Airframe, AirframeError, load_airframe
from autopilot.control.cascade import CascadeController, CascadeDiagnostics
from autopilot.control.gains import CHANNELS, CascadeGains, CascadeLimits, NlvgGains

__all__ = [
    "CHANNELS",
    "Airframe",
    "AirframeError",
    "CascadeController",
    "CascadeDiagnostics",
    "CascadeGains",
    "CascadeLimits",
    "NlvgGains",
    "load_airframe",
]
