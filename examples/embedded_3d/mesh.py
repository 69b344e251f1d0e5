"""Meshes of the 3D embedded-crack examples: structured boxes of hexahedra.

    python mesh.py [--divisions 8 2 16] [--out prism.msh]   # the 40 x 40 x 80 mm prism (inclined_joint.toml)
    python mesh.py --box [--out box.msh]                     # one 40 x 80 x 80 mm cell (paper_ede_3d.toml)
"""

import argparse
from pathlib import Path

from rockfrac.mesh.rock_tests import box

HERE = Path(__file__).parent

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--box", action="store_true", help="the paper's one-cell box instead of the prism")
    p.add_argument("--divisions", type=int, nargs=3, default=[8, 2, 16], help="prism cells along x, y, z")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args()
    if args.box:
        print(box(args.out or HERE / "box.msh", (0.04, 0.08, 0.08), (1, 1, 1), element="hex8"))
    else:
        print(box(args.out or HERE / "prism.msh", (0.04, 0.04, 0.08), tuple(args.divisions), element="hex8"))
