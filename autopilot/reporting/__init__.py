"""What the autopilot reports: the per-step record for listeners, the GCS snapshot, tracking and the summary."""
