"""The paper's report as markdown (``paper_table.md``): Table 1 with NLVG/PID ratios, the tracking, portability
and payload tables of the noise-free setting, then the noisy, effort-aware setting with its 95 % CIs."""

from __future__ import annotations

import math
from typing import Any


def _fmt(v: float, digits: int = 4, inf_text: str = "diverged") -> str:
    return inf_text if not math.isfinite(v) else f"{v:.{digits}g}"


def markdown(table: dict[str, Any], extras: dict[str, Any]) -> str:
    """``paper_table.md``: the tables of ``paper_table.json`` and ``paper_extras.json`` as the paper lays them out."""
    r = extras["ratios"]
    lines = [
        "# Fixed PID vs NLVG-PID + ES (paper Table 1 layout)",
        "",
        f"Vehicle {extras['vehicle']}; both structures tuned by the same central-difference ES "
        f"({extras['budget']['restarts']} restarts; rollouts: PID {extras['budget']['rollouts']['pid']}, "
        f"NLVG {extras['budget']['rollouts']['nlvg']}). Attitude errors in degrees (t_peak 0.15 s), "
        "position errors in m (t_peak 0.37 s).",
        "",
        "| Channel | PID IAE | PID ITAE | PID ITSE | | NLVG IAE | NLVG ITAE | NLVG ITSE "
        "| IAE ratio | ITAE ratio | ITSE ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    labels = {"phi": "φ (roll, °)", "theta": "θ (pitch, °)", "x": "x (m)", "y": "y (m)"}
    for ch, row in table["step"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {labels[ch]} | {_fmt(p['IAE'])} | {_fmt(p['ITAE'])} | {_fmt(p['ITSE'])} | "
            f"| {_fmt(n['IAE'])} | {_fmt(n['ITAE'])} | {_fmt(n['ITSE'])} "
            f"| {_fmt(r[ch]['IAE'], 3)} | {_fmt(r[ch]['ITAE'], 3)} | {_fmt(r[ch]['ITSE'], 3)} |"
        )
    lines += [
        "",
        "Paper's ratios: IAE 0.90-0.91, ITAE 0.86-0.92, ITSE 0.79-0.85.",
        "",
        "## Route tracking (RMS of the error norm)",
        "",
        "| Route | PID pos (m) | NLVG pos (m) | pos change | PID att (°) | NLVG att (°) | att change |",
        "|---|---|---|---|---|---|---|",
    ]
    for route in ("storm", "lissajous"):
        p, n = table[route]["pid"], table[route]["nlvg"]
        rp, ra = r[route]["pos_rms_m"], r[route]["att_rms_deg"]
        lines.append(
            f"| {route} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} | {_pct(rp)} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} | {_pct(ra)} |"
        )
    rc = extras["ratios_small_steps_and_calm_routes"]
    lines += [
        "",
        f"Routes flown in wind: mean {extras['routes_wind']['mean_ned_m_s']} m/s NED, gusts "
        f"{extras['routes_wind']['gust_m_s']} m/s (1σ), the same seeded gusts for both controllers. In calm air:",
        "",
        "| Route (calm) | PID pos (m) | NLVG pos (m) | pos change | PID att (°) | NLVG att (°) | att change |",
        "|---|---|---|---|---|---|---|",
    ]
    for route in ("storm", "lissajous"):
        p, n = extras["routes_calm"][route]["pid"], extras["routes_calm"][route]["nlvg"]
        lines.append(
            f"| {route} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} | {_pct(rc[route]['pos_rms_m'])} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} | {_pct(rc[route]['att_rms_deg'])} |"
        )
    lines += [
        "",
        "Small steps (0.02 rad, 0.05 m), NLVG/PID ratios: "
        + ", ".join(
            f"{ch} IAE {_fmt(rc[ch]['IAE'], 3)} ITAE {_fmt(rc[ch]['ITAE'], 3)} ITSE {_fmt(rc[ch]['ITSE'], 3)}"
            for ch in ("phi", "theta", "x", "y")
        ),
        "",
        "Paper's Lissajous claim: attitude error −50 %, position error −15 %.",
        "",
        "## Portability: gains tuned on x500, unchanged, Lissajous route (in the same wind)",
        "",
        "| Vehicle | PID pos (m) | NLVG pos (m) | PID att (°) | NLVG att (°) |",
        "|---|---|---|---|---|",
    ]
    for vehicle, row in extras["portability"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {vehicle} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} |"
        )
    lines += [
        "",
        f"## Payload change mid-hover ({extras['payload_vehicle']}, controller not told)",
        "",
        "| Change | Mass (kg) | PID max alt dev (m) | NLVG max alt dev (m) | PID recovery (s) | NLVG recovery (s) |",
        "|---|---|---|---|---|---|",
    ]
    nr = "not recovered"
    for key, row in extras["payload"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {key} | {p['mass_before_kg']:.3g} → {p['mass_after_kg']:.3g} | {_fmt(p['max_alt_dev_m'])} "
            f"| {_fmt(n['max_alt_dev_m'])} | {_fmt(p['recovery_s'], inf_text=nr)} "
            f"| {_fmt(n['recovery_s'], inf_text=nr)} |"
        )
    lines += ["", f"Recovery: time until |altitude error| stays below {extras['recovery_band_m']} m.", ""]
    lines += noisy_markdown(extras)
    return "\n".join(lines)


def _mci(mc: dict[str, float], digits: int = 3) -> str:
    """``mean ± ci95``."""
    return f"{_fmt(mc['mean'], digits)} ± {_fmt(mc['ci95'], 2)}"


def noisy_markdown(extras: dict[str, Any]) -> list[str]:
    """The noisy effort-aware setting: ratios with 95 % CIs over the held-out seeds, step shape, hover, sweep."""
    nz = extras["noisy_effort"]
    shape = extras["step_overshoot_settling"]
    lines = [
        "## Noise-free large steps: overshoot and 5 % settling time",
        "",
        "| Channel | PID overshoot | NLVG overshoot | PID settling (s) | NLVG settling (s) |",
        "|---|---|---|---|---|",
    ]
    for ch, row in shape.items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {ch} | {p['overshoot']:.1%} | {n['overshoot']:.1%} | {_fmt(p['settling_s'], 3)} "
            f"| {_fmt(n['settling_s'], 3)} |"
        )
    lines += [
        "",
        "# The noisy, effort-aware setting",
        "",
        f"Feedback noise: white + Gauss-Markov drift on position, velocity, attitude and rates "
        f"(`tools/research/experiments/feedback_noise.py`); training seeds {nz['train_seeds']}, evaluation on held-out "
        f"seeds {nz['eval_seeds']} (mean ± 95 % CI over seeds; ratios NLVG/PID taken per seed, both structures "
        f"meet the same noise and gusts). Cost: true-error mean e² + λ·chatter² + μ·overshoot², λ = "
        f"{nz['effort_weight']} × {nz['headline_effort_scale']:g}, μ = {nz['overshoot_weight']}. "
        "PID tuned first, NLVG (k1, k2, δ1, δ2) warm-started at it.",
        "",
        "| Channel | IAE ratio | ITAE ratio | ITSE ratio | PID overshoot | NLVG overshoot | PID settling (s) "
        "| NLVG settling (s) | chatter ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for ch, row in nz["steps"].items():
        r, v = row["ratio"], row["values"]
        lines.append(
            f"| {ch} | {_mci(r['IAE'])} | {_mci(r['ITAE'])} | {_mci(r['ITSE'])} | {v['pid']['overshoot']:.1%} "
            f"| {v['nlvg']['overshoot']:.1%} | {_fmt(v['pid']['settling_s'], 3)} | {_fmt(v['nlvg']['settling_s'], 3)} "
            f"| {_mci(r['chatter_per_s'])} |"
        )
    lines += [
        "",
        "| Route / hover (wind) | PID pos (m) | NLVG pos (m) | pos ratio | PID att (°) | NLVG att (°) | att ratio "
        "| chatter ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in ("storm", "lissajous", "hover"):
        row = nz[name]
        v, r = row["values"], row["ratio"]
        lines.append(
            f"| {name} | {_fmt(v['pid']['pos_rms_m'])} | {_fmt(v['nlvg']['pos_rms_m'])} | {_mci(r['pos_rms_m'])} "
            f"| {_fmt(v['pid']['att_rms_deg'])} | {_fmt(v['nlvg']['att_rms_deg'])} | {_mci(r['att_rms_deg'])} "
            f"| {_mci(r['chatter_per_s'])} |"
        )
    lines += [
        "",
        "λ sweep (`tradeoff_noisy.png`): per λ multiplier, both structures re-tuned; 1 m x-step RMS true error, "
        "hover attitude jitter and motor chatter on the held-out seeds.",
        "",
        "| λ× | PID step (m) | NLVG step (m) | PID jitter (°) | NLVG jitter (°) | PID chatter (1/s) "
        "| NLVG chatter (1/s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for pt in nz["tradeoff"]:
        p, n = pt["pid"], pt["nlvg"]
        lines.append(
            f"| {pt['effort_scale']:g} | {_fmt(p['step_rms_m'])} | {_fmt(n['step_rms_m'])} | {_fmt(p['jitter_deg'])} "
            f"| {_fmt(n['jitter_deg'])} | {_fmt(p['chatter_per_s'])} | {_fmt(n['chatter_per_s'])} |"
        )
    jw = nz["j_nlvg_warm_start_at_pid"]
    lines += [
        "",
        "ES cost J (training seeds), initial → best: "
        + ", ".join(f"{k} {_fmt(v[0])} → {_fmt(v[1])}" for k, v in nz["j"].items())
        + "; the NLVG's J at its warm start (the tuned PID's gains): "
        + ", ".join(f"{k} {_fmt(v)}" for k, v in jw.items())
        + ".",
        "",
    ]
    return lines


def _pct(ratio: float) -> str:
    return "n/a" if not math.isfinite(ratio) else f"{(ratio - 1.0) * 100.0:+.1f} %"
