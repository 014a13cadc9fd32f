"""Wrap one object on one plane and watch it in Meshcat (Drake's browser viewer).

Prints the viewer's URL; with --html the animation is also saved as one page.
"""

import argparse
import sys
from pathlib import Path

from drake_continuum.kinematics.arm import load_arm
from drake_continuum.viz.meshcat import show_wrap, wrap_title
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import wrap


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--mesh", default="models/mug.obj",
                        help="object mesh (default: models/mug.obj)")
    parser.add_argument("--plane", type=int, default=0, help="wrap plane index (default: 0)")
    parser.add_argument("--html", default=None, help="save the animation here (default: none)")
    args = parser.parse_args()

    arm = load_arm()
    scene = WrapScene(arm, args.mesh)
    plane = enumerate_planes(arm.base_position)[args.plane]
    result = wrap(scene, plane)
    print(f"{result.status}: {len(result.contacts)} contacts, tip turned "
          f"{result.tip_rotation * 57.2958:.0f} deg in {result.time_s * 1000:.0f} ms")
    meshcat, _ = show_wrap(arm.with_base(rotation=result.base_rotation), args.mesh,
                           result.configs, contacts=result.contacts, html_path=args.html,
                           title=wrap_title(Path(args.mesh).stem, plane.label, result))
    print(f"Meshcat: {meshcat.web_url()}")
    if sys.stdin.isatty():  # keep the viewer's server up while someone is looking
        input("Press Enter to quit.")


if __name__ == "__main__":
    main()
