"""Draw shipped maps side by side (docs/figures/maps.png).

    python3 scripts/plot_maps.py [--out docs/figures/maps.png] [NAME ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from aoass_env.atomic import folder_problem, save_figure_atomic  # noqa: E402
from aoass_env.maps import MapError, load_map  # noqa: E402

DEFAULT = ["test/d0.10_f100_s500", "test/d0.30_f100_s506", "test/d0.60_f100_s515",
           "test/d0.60_f200_s533"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", default=DEFAULT, help="shipped map names or paths")
    parser.add_argument("--out", type=Path, default=Path("docs/figures/maps.png"))
    args = parser.parse_args()
    # checked before drawing: a file where a folder should be said "File exists" at the end
    if args.out.is_dir():
        parser.error(f"--out {args.out}: is a folder; give the figure's file name")
    problem = folder_problem(args.out.parent)
    if problem:
        parser.error(f"--out {args.out}: {problem}")
    fig, axes = plt.subplots(1, len(args.names), figsize=(4 * len(args.names), 4.2),
                             squeeze=False)
    for ax, name in zip(axes[0], args.names, strict=True):
        try:
            m = load_map(name)
        except MapError as exc:     # of a folder it said "no such file"
            parser.error(f"{name}: a folder, not a map file; give map files or shipped map "
                         f"names (e.g. {DEFAULT[0]})" if Path(name).is_dir() else str(exc))
        for poly in m.polygons:
            ax.add_patch(Polygon(poly, closed=True, color="0.45"))
        ax.set(xlim=(0, m.width), ylim=(0, m.height), aspect="equal",
               title=f"{name}: density {m.density:.3f}")
    fig.tight_layout()
    try:
        save_figure_atomic(fig, args.out, dpi=80)
    except (OSError, ValueError) as exc:
        parser.error(f"--out {args.out}: {getattr(exc, 'strerror', None) or exc}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
