"""Mesh of the triaxial examples: a 50 mm x 100 mm cylinder of tetrahedra, optionally cut by a joint
through its centre.

    python mesh.py [--size 0.00625] [--joint-dip DEG] [--out cylinder.msh]
"""

import argparse
import math
from pathlib import Path

from rockfrac.mesh.rock_tests import cylinder

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--size", type=float, default=0.00625, help="element size [m]")
    p.add_argument("--joint-dip", type=float, default=None, help="dip of a joint through the centre [deg]")
    p.add_argument("--out", type=Path, default=Path(__file__).with_name("cylinder.msh"))
    args = p.parse_args()
    dip = None if args.joint_dip is None else math.radians(args.joint_dip)
    cylinder(args.out, diameter=0.05, height=0.1, element_size=args.size, joint_dip=dip)
    print(args.out)
