"""Mesh of the three-point bending example: a 200 x 50 mm beam, a 15 mm deep, 2 mm wide notch at the
bottom centre, the ligament above it an internal curve, supports 160 mm apart.

    python mesh.py [--size 0.0025] [--out beam.msh]
"""

import argparse
from pathlib import Path

from rockfrac.mesh.rock_tests import notched_beam

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--size", type=float, default=0.0025, help="element size [m]")
    p.add_argument("--out", type=Path, default=Path(__file__).with_name("beam.msh"))
    args = p.parse_args()
    notched_beam(args.out, length=0.2, height=0.05, span=0.16, notch_depth=0.015, notch_width=0.002,
                 element_size=args.size)
    print(args.out)
