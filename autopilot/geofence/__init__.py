"""The geofence (SPEC §7, §10): the uploaded FENCE as zones about home, and as the avoidance planner's fence zones.
Missions are checked against it, routes go around it, the failsafe watches for a breach."""
