"""Performance metrics of SPEC §6.4 (paper Table 1 footnote) and the ES cost of SPEC §6.3.

Every function works on a batch: errors/responses shaped (n, T) (or (T,) for one signal) sampled at
times ``t_s`` (T,), strictly increasing. Integrals use the trapezoidal rule, cut exactly at the end time
by linear interpolation. Time is measured from ``t_s[0]`` (the step instant).

    IAE  = (1/t_peak) ∫₀^t_peak |e| dt      ITAE = (1/t_peak) ∫₀^t_peak t·|e| dt
    ITSE = (1/t_peak) ∫₀^t_peak t·e² dt      J    = (1/(t_f − t_0)) ∫_t0^tf e² dt
"""

from __future__ import annotations

import numpy as np

#: the paper's integration windows (section 4): attitude 0.15 s, position 0.37 s
T_PEAK_ATTITUDE_S = 0.15
T_PEAK_POSITION_S = 0.37


def _prepare(e: np.ndarray, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e = np.asarray(e, dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    if t.ndim != 1 or t.size < 2 or e.shape[-1] != t.size:
        raise ValueError(f"need t_s of shape (T,), T >= 2, matching the last axis of the signal {e.shape}")
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("t_s must be strictly increasing")
    return e, t


def _interp_last(f: np.ndarray, t: np.ndarray, tk: float) -> np.ndarray:
    """f linearly interpolated at time tk along the last axis (tk inside [t[0], t[-1]])."""
    j = int(np.clip(np.searchsorted(t, tk), 1, t.size - 1))
    a = (tk - t[j - 1]) / (t[j] - t[j - 1])
    return (1.0 - a) * f[..., j - 1] + a * f[..., j]


def integrate(f: np.ndarray, t_s: np.ndarray, t0_s: float | None = None, tf_s: float | None = None) -> np.ndarray:
    """∫ f dt over [t0, tf] (defaults: the whole record) along the last axis; trapezoid, exact cut."""
    f, t = _prepare(f, t_s)
    t0 = t[0] if t0_s is None else float(t0_s)
    tf = t[-1] if tf_s is None else float(tf_s)
    if not (t[0] <= t0 < tf <= t[-1] + 1e-12):
        raise ValueError(f"window [{t0}, {tf}] s must lie inside the record [{t[0]}, {t[-1]}] s")
    tf = min(tf, t[-1])
    inner = (t > t0) & (t < tf)
    grid = np.concatenate(([t0], t[inner], [tf]))
    idx = np.concatenate(([0], np.nonzero(inner)[0], [0]))
    vals = np.empty((*f.shape[:-1], grid.size))
    vals[..., 1:-1] = f[..., idx[1:-1]]
    vals[..., 0] = _interp_last(f, t, t0)
    vals[..., -1] = _interp_last(f, t, tf)
    return np.trapezoid(vals, grid, axis=-1)


def iae(e: np.ndarray, t_s: np.ndarray, t_peak_s: float) -> np.ndarray:
    """IAE = (1/t_peak) ∫₀^t_peak |e| dt (paper Table 1)."""
    e, t = _prepare(e, t_s)
    return integrate(np.abs(e), t, t[0], t[0] + t_peak_s) / t_peak_s


def itae(e: np.ndarray, t_s: np.ndarray, t_peak_s: float) -> np.ndarray:
    """ITAE = (1/t_peak) ∫₀^t_peak t·|e| dt (paper Table 1)."""
    e, t = _prepare(e, t_s)
    return integrate((t - t[0]) * np.abs(e), t, t[0], t[0] + t_peak_s) / t_peak_s


def itse(e: np.ndarray, t_s: np.ndarray, t_peak_s: float) -> np.ndarray:
    """ITSE = (1/t_peak) ∫₀^t_peak t·e² dt (paper Table 1)."""
    e, t = _prepare(e, t_s)
    return integrate((t - t[0]) * e * e, t, t[0], t[0] + t_peak_s) / t_peak_s


def es_cost(e: np.ndarray, t_s: np.ndarray, t0_s: float | None = None, tf_s: float | None = None) -> np.ndarray:
    """ES cost J = (1/(t_f − t_0)) ∫ e² dt (paper eq. 12); sum e² over components first if e is (n, k, T)."""
    e, t = _prepare(e, t_s)
    t0 = t[0] if t0_s is None else t0_s
    tf = t[-1] if tf_s is None else tf_s
    return integrate(e * e, t, t0, tf) / (tf - t0)


def rms(e: np.ndarray, axis: int = -1) -> np.ndarray:
    """Root mean square of the samples along ``axis``."""
    e = np.asarray(e, dtype=np.float64)
    return np.sqrt(np.mean(e * e, axis=axis))


def max_abs(e: np.ndarray, axis: int = -1) -> np.ndarray:
    """Largest |e| along ``axis``."""
    return np.max(np.abs(np.asarray(e, dtype=np.float64)), axis=axis)


def overshoot(y: np.ndarray, y0: float | np.ndarray, y_sp: float | np.ndarray) -> np.ndarray:
    """Overshoot of a step response from y0 to y_sp, as a fraction of the step (0 when none)."""
    y = np.asarray(y, dtype=np.float64)
    step = np.asarray(y_sp, dtype=np.float64) - np.asarray(y0, dtype=np.float64)
    if np.any(step == 0.0):
        raise ValueError("overshoot: the step y_sp − y0 must be non-zero")
    past = (y - np.expand_dims(y_sp, -1)) * np.expand_dims(np.sign(step), -1)
    return np.maximum(np.max(past, axis=-1), 0.0) / np.abs(step)


def settling_time(
    y: np.ndarray, t_s: np.ndarray, y0: float | np.ndarray, y_sp: float | np.ndarray, band: float = 0.05
) -> np.ndarray:
    """Time from t_s[0] after which |y − y_sp| stays within band·|step|; inf if it never settles."""
    y, t = _prepare(y, t_s)
    step = np.abs(np.asarray(y_sp, dtype=np.float64) - np.asarray(y0, dtype=np.float64))
    outside = np.abs(y - np.expand_dims(y_sp, -1)) > band * np.expand_dims(step, -1)
    rev = outside[..., ::-1]
    last_out = outside.shape[-1] - 1 - np.argmax(rev, axis=-1)
    any_out = np.any(outside, axis=-1)
    settled_at = np.where(any_out, np.minimum(last_out + 1, t.size - 1), 0)
    out = t[settled_at] - t[0]
    return np.where(any_out & (last_out == t.size - 1), np.inf, out)


def rise_time(y: np.ndarray, t_s: np.ndarray, y0: float | np.ndarray, y_sp: float | np.ndarray) -> np.ndarray:
    """10 %–90 % rise time of a step response; inf if 90 % is never reached."""
    y, t = _prepare(y, t_s)
    y0a = np.expand_dims(np.asarray(y0, dtype=np.float64), -1)
    step = np.expand_dims(np.asarray(y_sp, dtype=np.float64), -1) - y0a
    frac = (y - y0a) / step
    reach10 = np.argmax(frac >= 0.1, axis=-1)
    reach90 = np.argmax(frac >= 0.9, axis=-1)
    never = ~np.any(frac >= 0.9, axis=-1)
    return np.where(never, np.inf, t[reach90] - t[reach10])
