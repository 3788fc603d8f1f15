"""Flight tasks (PX4 FlightTasks): what the vehicle is asked to fly in each mode, as a ``NavTarget``, and the
smooth setpoints toward it; the parametric reference trajectories of SPEC §6.5."""
