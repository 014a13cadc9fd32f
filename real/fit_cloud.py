"""Fit the continuum arm's configuration to a depth-camera point cloud.

Thin wrapper of `drake-continuum fit-cloud`; see `python real/fit_cloud.py --help`.
Example: python real/fit_cloud.py real/data/cylinder_0.pcd --png out/fit.png
"""

import sys

from drake_continuum.cli import main

if __name__ == "__main__":
    sys.exit(main(["fit-cloud", *sys.argv[1:]]))
