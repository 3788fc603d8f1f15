"""The vehicle side of the GCS/API links (SPEC §3, §8): the server and the protocols a ground station talks to
(commands, missions, parameters, offboard setpoints, manual control, FTP) and the telemetry streams."""
