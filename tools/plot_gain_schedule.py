"""Plot k(s) of SPEC §6.1: the raised-cosine default against the paper-literal formula (eq. 5 as printed).

Usage: ``python -m tools.plot_gain_schedule [--out results/gain_schedule.png] [--k1 2 --k2 6]``.
The literal formula completes a whole cosine period inside [δ1, δ2], returns to ≈ k1 at δ2 and then
jumps to k2; the raised cosine rises monotonically and continuously from k1 to k2.
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
from autopilot.control.gains import PAPER_DELTA1, PAPER_DELTA2


def plot_gain_schedule(out: Path, k1: float = 2.0, k2: float = 6.0) -> Path:
    """Write the comparison figure to ``out`` (PNG) and return the path."""
    s = np.linspace(0.0, 1.2, 4001)
    fig, ax = plt.subplots(figsize=(7.0, 4.0), dpi=120)
    for variant, style in ((GainVariant.RAISED_COSINE, "-"), (GainVariant.PAPER_LITERAL, "--")):
        ax.plot(s, variable_gain(s, k1, k2, PAPER_DELTA1, PAPER_DELTA2, variant), style, label=variant.name.lower())
    for d, name in ((PAPER_DELTA1, "δ1"), (PAPER_DELTA2, "δ2")):
        ax.axvline(d, color="grey", lw=0.8, ls=":")
        ax.text(d, k2 * 1.02, name, ha="center", va="bottom")
    ax.set_xlabel("|s| (scheduling signal, default |e|)")
    ax.set_ylabel("k(s)")
    ax.set_title(f"NLVG variable gain, k1 = {k1:g}, k2 = {k2:g}, δ1 = {PAPER_DELTA1}, δ2 = {PAPER_DELTA2}")
    ax.set_ylim(min(k1, k2) - 0.5, max(k1, k2) * 1.12)
    ax.legend(loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.plot_gain_schedule", description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("results/gain_schedule.png"))
    parser.add_argument("--k1", type=float, default=2.0)
    parser.add_argument("--k2", type=float, default=6.0)
    args = parser.parse_args(argv)
    print(plot_gain_schedule(args.out, args.k1, args.k2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
