"""The commander (SPEC §3, §8): arming, flight modes and landed state; scripted commands at fixed sim times."""
