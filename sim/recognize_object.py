"""Recognise an object by active wrapping: train on a wrap collection, then let the tree
search choose the wraps of a new mesh until the prediction is strong."""

import argparse
from dataclasses import replace

from drake_continuum.active.policies import recognize, simulated_execute
from drake_continuum.active.training import train_active
from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.mesh import load_mesh
from drake_continuum.perception.locate import camera_view
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("wraps", help="wrap collection (drake-continuum collect), required")
    parser.add_argument("--mesh", default="models/mug.obj",
                        help="object to recognise (default: models/mug.obj)")
    parser.add_argument("--seed", type=int, default=0, help="seed (default: 0)")
    args = parser.parse_args()

    model = train_active(args.wraps, seed=args.seed)
    arm = load_arm()
    scene = WrapScene(arm, args.mesh)
    execute = simulated_execute(scene, enumerate_planes(arm.base_position),
                                model.classifier.chord_params)
    scenario = load_config()
    result = recognize(model, execute, replace(scenario, active=replace(scenario.active,
                                                                        seed=args.seed)),
                       view=camera_view(load_mesh(args.mesh), arm))
    for k, it in enumerate(result.iterations, 1):
        print(f"iteration {k}: {it.n_wraps} wraps -> {it.top3}")
    print(f"recognised as {result.category} ({result.stopped_because})")


if __name__ == "__main__":
    main()
