"""Missions as data: MAVLink command numbers, mission files, upload validation, geofence zones and the executor.

Modules: ``commands`` (MAV_CMD/MAV_FRAME numbers), ``plan`` (MissionPlan), ``files`` (YAML v1,
QGC WPL 110, QGC .plan by extension; one ``file_*`` module per format), ``validation`` (upload checks),
``fence`` (zones in local NED), ``executor`` (the vehicle-agnostic state machine), ``param_decls`` (MIS_* parameters).
"""
