"""Figures like the paper's: step responses PID vs NLVG-PID, route angle/position errors, payload change.

Every figure expects batches with vehicle 0 = fixed PID and vehicle 1 = NLVG-PID (paper_pipeline order).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from tools.research.experiments.rollout import MassChangeTrace, StepTrace, TrackTrace

LABELS = ("PID (ES-tuned)", "NLVG-PID (ES-tuned)")
COLOURS = ("tab:blue", "tab:red")
TITLES = {"phi": "roll φ", "theta": "pitch θ", "x": "x", "y": "y"}


def plot_steps(traces: Mapping[str, StepTrace], keys: Sequence[str], path: Path, degrees: bool) -> None:
    """Step responses (paper Fig. 'attitude controller step response of PID and NLVG-PID')."""
    fig, axes = plt.subplots(1, len(keys), figsize=(5.0 * len(keys), 3.4), dpi=120, squeeze=False)
    unit = "deg" if degrees else "m"
    for ax, key in zip(axes[0], keys, strict=True):
        tr = traces[key]
        scale = np.degrees(1.0) if degrees else 1.0
        ax.axhline(tr.amplitude * scale, color="k", ls="--", lw=0.8, label="setpoint")
        for i in range(tr.response.shape[0]):
            ax.plot(tr.t_s, tr.response[i] * scale, color=COLOURS[i], lw=1.4, label=LABELS[i])
        ax.set_title(f"{TITLES.get(key, key)} step")
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"{TITLES.get(key, key)} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_tracking(tr: TrackTrace, route: str, path: Path) -> None:
    """Angle errors and position errors of both controllers along a route (paper Figs. 6-9, 11-14)."""
    fig, axes = plt.subplots(2, 2, figsize=(11.0, 6.4), dpi=120, sharex=True)
    for i in range(min(2, tr.pos_err_ned.shape[0])):
        ax_att, ax_pos = axes[0, i], axes[1, i]
        for k, name in enumerate(("φ_err", "θ_err", "ψ_err")):
            ax_att.plot(tr.t_s, np.degrees(tr.att_err_rad[i, :, k]), lw=0.8, label=name)
        for k, name in enumerate(("X_err", "Y_err", "Z_err")):
            ax_pos.plot(tr.t_s, tr.pos_err_ned[i, :, k], lw=0.8, label=name)
        ax_att.set_title(f"{LABELS[i]}: angle error, {route}")
        ax_pos.set_title(f"{LABELS[i]}: position error, {route}")
        ax_att.set_ylabel("deg")
        ax_pos.set_ylabel("m (NED)")
        ax_pos.set_xlabel("t (s)")
        for ax in (ax_att, ax_pos):
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7, loc="upper right")
    for row in range(2):  # same y-limits left and right so the two controllers compare at a glance
        lo = min(axes[row, 0].get_ylim()[0], axes[row, 1].get_ylim()[0])
        hi = max(axes[row, 0].get_ylim()[1], axes[row, 1].get_ylim()[1])
        axes[row, 0].set_ylim(lo, hi)
        axes[row, 1].set_ylim(lo, hi)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_mass_change(traces: Mapping[str, MassChangeTrace], vehicle: str, path: Path) -> None:
    """Altitude error around the mass change, −30 % and +30 %."""
    fig, axes = plt.subplots(1, len(traces), figsize=(5.2 * len(traces), 3.4), dpi=120, squeeze=False)
    for ax, (key, tr) in zip(axes[0], traces.items(), strict=True):
        for i in range(tr.alt_err_m.shape[0]):
            ax.plot(tr.t_s, -tr.alt_err_m[i], color=COLOURS[i], lw=1.2, label=LABELS[i])
        ax.axvline(tr.t_change_s, color="k", ls=":", lw=0.8)
        ax.set_title(f"{vehicle}: mass {key} ({tr.mass_before_kg:.2f} → {tr.mass_after_kg:.2f} kg)")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("altitude − setpoint (m)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_tradeoff(points: Sequence[dict], path: Path) -> None:
    """The λ sweep's trade-off curves, one PNG: step tracking error against hover attitude jitter (left) and
    hover motor chatter (right), PID and NLVG-PID, each point labelled with its λ multiplier."""
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.0), dpi=120)
    for ax, xkey, xlabel in (
        (axes[0], "jitter_deg", "hover attitude jitter (deg RMS, true)"),
        (axes[1], "chatter_per_s", "hover motor-command rate (1/s RMS)"),
    ):
        for i, s in enumerate(("pid", "nlvg")):
            xs = [p[s][xkey] for p in points]
            ys = [p[s]["step_rms_m"] for p in points]
            ax.plot(xs, ys, "o-", color=COLOURS[i], label=LABELS[i])
            for p, x, y in zip(points, xs, ys, strict=True):
                ax.annotate(f"λ×{p['effort_scale']:g}", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("1 m x step: RMS true position error (m)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Noisy feedback, effort-aware ES: tracking vs jitter and chatter (held-out seeds)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
