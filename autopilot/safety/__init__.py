"""Safety (SPEC §5b, §10): failsafes, injected failures, sensor validation, the land detector and link health."""
