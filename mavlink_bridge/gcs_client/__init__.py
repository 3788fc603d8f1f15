"""The ground-station client (SPEC §8): a session to one vehicle with missions, commands, parameters, its folded
telemetry and typed errors; and a listener for the standard telemetry of any MAVLink vehicle (tools/monitor.py)."""
