"""Mesh of the borehole examples: a quarter of a 3 m plate around a 50 mm hole (symmetry edges
left and bottom; the far edges 60 radii away, where Kirsch's perturbation is 3e-4 of the in-situ
stress), elements graded from the hole, and a ring region "near" (r < 0.15 m).

    python mesh.py [--size 0.005] [--out plate.msh]
"""

import argparse
from pathlib import Path

from rockfrac.mesh.rock_tests import plate_with_hole

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--size", type=float, default=0.005, help="element size at the hole [m]")
    p.add_argument("--out", type=Path, default=Path(__file__).with_name("plate.msh"))
    args = p.parse_args()
    plate_with_hole(args.out, radius=0.05, size=3.0, element_size=args.size, near_radius=0.15, grading=20.0)
    print(args.out)
