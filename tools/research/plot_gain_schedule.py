"""Plot k(s) of SPEC §6.1 (paper eqs. 4-9): a gain set's schedules, or the raised cosine against the paper literal.

Usage::

    python -m tools.research.plot_gain_schedule [--out results/gain_schedule.png] [--k1 2 --k2 6]
    python -m tools.research.plot_gain_schedule --gains autopilot/control/default_gains.yaml --out gains_k_of_s.png

Default: the raised-cosine default against the paper-literal formula (eq. 5 as printed), one term. The literal
formula completes a whole cosine period inside [δ1, δ2], returns to ≈ k1 at δ2 and then jumps to k2; the raised
cosine rises monotonically and continuously from k1 to k2.

``--gains FILE`` (a gains file, e.g. the shipped defaults or ``tools.research.tune_es`` output): one panel per channel
(x, y, z, roll, pitch, yaw), each with k_p(|e|), k_i(|e|) and k_d(|e|) over the channel's error (m or rad), δ1 and δ2
marked; every curve's legend names the term and the channel.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from autopilot.control.gain_schedule import GainVariant, variable_gain
from autopilot.control.gains import CHANNELS, PAPER_DELTA1, PAPER_DELTA2, CascadeGains

TERM_LABELS = ("k_p", "k_i", "k_d")
#: unit of each channel's error (the scheduling signal |e|)
ERROR_UNIT = {"x": "m", "y": "m", "z": "m", "roll": "rad", "pitch": "rad", "yaw": "rad"}


def plot_gain_schedule(out: Path, k1: float = 2.0, k2: float = 6.0) -> Path:
    """Write the variant comparison figure (one k_p term) to ``out`` (PNG) and return the path."""
    s = np.linspace(0.0, 1.2, 4001)
    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=120)
    for variant, style in ((GainVariant.RAISED_COSINE, "-"), (GainVariant.PAPER_LITERAL, "--")):
        k = variable_gain(s, k1, k2, PAPER_DELTA1, PAPER_DELTA2, variant)
        ax.plot(s, k, style, label=f"k_p(|e|), {variant.name.lower()}")
    for d, name in ((PAPER_DELTA1, "δ1"), (PAPER_DELTA2, "δ2")):
        ax.axvline(d, color="grey", lw=0.8, ls=":")
        ax.text(d, k2 * 1.02, name, ha="center", va="bottom")
    ax.set_xlabel("|s| (scheduling signal, default |e|)")
    ax.set_ylabel("k_p(s)")
    ax.set_title(f"NLVG variable gain k_p, k1 = {k1:g}, k2 = {k2:g}, δ1 = {PAPER_DELTA1}, δ2 = {PAPER_DELTA2}")
    ax.set_ylim(min(k1, k2) - 0.5, max(k1, k2) * 1.12)
    ax.legend(loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out


def plot_gain_set(gains: CascadeGains, out: Path, title: str = "") -> Path:
    """k_p, k_i, k_d against |e| for every channel of ``gains`` (one panel each, log-scaled k) into ``out``."""
    fig, axes = plt.subplots(2, 3, figsize=(12.0, 6.5), dpi=120)
    for ax, ch in zip(axes.ravel(), CHANNELS, strict=True):
        g = getattr(gains, ch)
        d1, d2 = float(g.delta1), float(g.delta2)
        s = np.linspace(0.0, 1.3 * d2, 2001)
        variant = GainVariant.parse(g.variant)
        for t, label in enumerate(TERM_LABELS):
            k = variable_gain(s, float(g.k1[t]), float(g.k2[t]), d1, d2, variant)
            ax.plot(s, k, label=f"{label} ({ch})")
        for d, name in ((d1, "δ1"), (d2, "δ2")):
            ax.axvline(d, color="grey", lw=0.8, ls=":")
            ax.annotate(name, (d, 1.0), xycoords=("data", "axes fraction"), ha="center", va="bottom", fontsize=8)
        ax.set_yscale("log")
        ax.set_title(f"channel {ch}")
        ax.set_xlabel(f"|e| ({ERROR_UNIT[ch]})")
        ax.set_ylabel("gain (normalised)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle(title or "NLVG-PID gain schedules k(|e|) per channel and term")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.research.plot_gain_schedule", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--out", type=Path, default=Path("results/gain_schedule.png"))
    parser.add_argument("--k1", type=float, default=2.0)
    parser.add_argument("--k2", type=float, default=6.0)
    parser.add_argument("--gains", type=Path, default=None, help="plot this gains file's k(s) per channel and term")
    args = parser.parse_args(argv)
    if args.gains is not None:
        try:
            gains = CascadeGains.from_yaml(args.gains)
        except ValueError as exc:
            print(f"plot_gain_schedule: error: {exc}", file=sys.stderr)
            return 2
        print(plot_gain_set(gains, args.out, f"k(|e|) of {args.gains}"))
        return 0
    print(plot_gain_schedule(args.out, args.k1, args.k2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
