"""Compare a real wrap (a point cloud) with the simulated wrap at the fitted configuration
(the paper's section V-D and Fig. 8).

Thin wrapper of `drake-continuum compare-real`; see `python real/compare_real.py --help`.
Example: python real/compare_real.py real/data/cylinder_0.pcd --object real/data/cylinder.obj
    --png out/fig8.png
"""

import sys

from drake_continuum.cli import main

if __name__ == "__main__":
    sys.exit(main(["compare-real", *sys.argv[1:]]))
