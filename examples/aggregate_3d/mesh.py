"""Mesh of the 3D aggregate example: a 50 x 50 x 100 mm prism of tetrahedra in Voronoi grains.

    python mesh.py [--cells 6 6 12] [--grains 12] [--seed 0] [--out aggregate.msh]
"""

import argparse
from pathlib import Path

from rockfrac.mesh.aggregate import grain_box

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--cells", type=int, nargs=3, default=[6, 6, 12], help="hexahedra along x, y, z (6 tets each)")
    p.add_argument("--grains", type=int, default=12)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path(__file__).with_name("aggregate.msh"))
    args = p.parse_args()
    grain_box(args.out, (0.05, 0.05, 0.1), tuple(args.cells), args.grains, args.seed)
    print(args.out)
