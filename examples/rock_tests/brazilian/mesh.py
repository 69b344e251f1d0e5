"""Mesh of the Brazilian disc examples: a 50 mm disc loaded over two 10 degree arcs, its vertical
diameter an internal curve (where the splitting crack may go).

    python mesh.py [--size 0.0025] [--out disc.msh]
"""

import argparse
import math
from pathlib import Path

from rockfrac.mesh.rock_tests import disc

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--size", type=float, default=0.0025, help="element size [m]")
    p.add_argument("--out", type=Path, default=Path(__file__).with_name("disc.msh"))
    args = p.parse_args()
    disc(args.out, diameter=0.05, contact_angle=math.radians(10.0), element_size=args.size)
    print(args.out)
