"""Navigation: what to fly in AUTO_MISSION, about home (missions, fences, avoidance)."""

from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.navigator import Navigator
from autopilot.navigation.outputs import NavOutput, ReferenceOverride

__all__ = ["HomeFrame", "NavOutput", "Navigator", "ReferenceOverride"]
