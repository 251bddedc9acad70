"""Draw the Eq. 7 fuzzy controller: membership functions and control surfaces.

    python3 scripts/plot_fuzzy.py [--out docs/figures/fuzzy.png]

Top row: the terms of d (m), dtheta (deg), omega (fraction of the maximum turn rate) and v
(fraction of the desired speed). Bottom row: omega(d, dtheta) and v(d, dtheta) of the default
controller. The PNG is written atomically (aoass_env.atomic).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from aoass_env.atomic import save_figure_atomic  # noqa: E402
from aoass_env.safety.fuzzy import FuzzyController, FuzzyVariable  # noqa: E402


def draw_terms(ax, var: FuzzyVariable, label: str, scale: float = 1.0) -> None:
    """Membership functions of ``var`` on ``ax``; x values multiplied by ``scale``."""
    x = np.linspace(var.universe[0], var.universe[1], 1001)
    for name, mu in zip(var.terms, np.moveaxis(var.memberships(x), -1, 0), strict=True):
        ax.plot(x * scale, mu, label=name)
    ax.set(xlabel=label, ylabel="membership", ylim=(-0.03, 1.3),
           xlim=(var.universe[0] * scale, var.universe[1] * scale))
    ax.legend(fontsize=7, ncols=len(var.terms), loc="upper center", frameon=False,
              handlelength=1.2, columnspacing=0.8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures/fuzzy.png"))
    args = parser.parse_args()
    flc = FuzzyController()
    deg = 180.0 / math.pi
    fig = plt.figure(figsize=(14, 7.5))
    grid = fig.add_gridspec(2, 4, height_ratios=[1, 1.5])
    draw_terms(fig.add_subplot(grid[0, 0]), flc.distance, "d: gap to nearest obstacle (m)")
    draw_terms(fig.add_subplot(grid[0, 1]), flc.heading, "Δθ: heading error (deg)", deg)
    draw_terms(fig.add_subplot(grid[0, 2]), flc.turn, "ω: fraction of max turn rate")
    draw_terms(fig.add_subplot(grid[0, 3]), flc.speed, "v: fraction of desired speed")

    d = np.linspace(*flc.distance.universe[:2], 201)
    h = np.linspace(*flc.heading.universe[:2], 181)
    dd, hh = np.meshgrid(d, h)
    omega, speed = flc(dd, hh)
    for col, (values, title, cmap, lim) in enumerate([
            (omega, "ω(d, Δθ)", "coolwarm", (-1, 1)), (speed, "v(d, Δθ)", "viridis", (0, 1))]):
        ax = fig.add_subplot(grid[1, 2 * col:2 * col + 2])
        mesh = ax.pcolormesh(d, h * deg, values, cmap=cmap, vmin=lim[0], vmax=lim[1],
                             shading="gouraud")
        ax.contour(d, h * deg, values, levels=np.linspace(lim[0], lim[1], 11), colors="k",
                   linewidths=0.4)
        ax.set(xlabel="d (m)", ylabel="Δθ (deg)", title=title, yticks=range(-180, 181, 45))
        fig.colorbar(mesh, ax=ax)
    fig.suptitle("Eq. 7 fuzzy controller f_FLC(d, Δθ) = [ω, v]: Mamdani, min/max, centroid")
    fig.tight_layout()
    try:
        save_figure_atomic(fig, args.out, dpi=80)
    except (OSError, ValueError) as exc:
        parser.error(f"--out {args.out}: {getattr(exc, 'strerror', None) or exc}")
    plt.close(fig)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
