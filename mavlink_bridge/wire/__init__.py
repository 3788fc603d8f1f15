"""The wire: MAVLink bytes <-> the typed contract (codec, decode, framing, compiled frame reader/writer), UDP links,
the GCS-link endpoint with signing, the lossy relay and mission-item conversions shared by both ends."""
