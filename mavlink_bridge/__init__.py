"""The only code that knows MAVLink: links, codec, lockstep and GCS protocols, and the typed wire contract.

``frames`` and ``wire`` import no pymavlink and may be used by sim and autopilot freely.
"""
