"""`evaluate`, `train`, `show-wraps`, `classify`: the chord classifier.
"""

from __future__ import annotations

from .common import (
    UserError,
    add_config_options,
    add_json,
    add_observe_options,
    add_placed_mesh_options,
    add_simplify,
    add_strict,
    check_categories,
    check_out_apart,
    command_config,
    config_planes,
    load_objects,
    observation_summary,
    observe_options,
    placed_scene,
    print_json,
    saved_model_config,
    shortcut,
)

__all__ = ["COMMANDS"]


def _add_evaluate(subparsers):
    p = subparsers.add_parser(
        "evaluate", help="accuracy over random 50/50 splits, chords and the triangle baseline",
        description="Classify the objects of a wrap collection over random stratified 50/50 "
                    "splits (the paper's V-B) with chord histograms and with [1]'s triangle "
                    "histograms on the same splits; write the confusion matrices (PNG), "
                    "Table I (Markdown, JSON) and evaluation.json. "
                    "Example: drake-continuum evaluate data/wraps --out results/evaluate")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--splits", type=int, default=100, help="random splits (default: 100)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--frame", choices=["world", "wrap", "upright", "plane"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    p.add_argument("--out", default="results/evaluate",
                   help="output folder (default: results/evaluate)")
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="also test on placed copies: the wrap collection of `objects place` "
                        "output (repeatable); accuracy as generated, turned, on another "
                        "side, nudged and the flip rate, splits by object, in "
                        "OUT/placements.md and .json (default: none)")
    p.add_argument("--train-kinds", default="generated",
                   help="with --placed, the records trained on: generated (the originals) "
                        "and/or the training placements train (a rest pose by its "
                        "probability) and side (the most probable other side), e.g. "
                        "generated,train,side (default: generated)")
    p.add_argument("--turn-invariant", action="store_true",
                   help="wrap descriptors pooled over planes and the contact extent along "
                        "the contacts' own horizontal axes, unchanged when the object turns, "
                        "a shortcut for --set classifier.turn_invariant=true (default: the "
                        "configuration's, off: one slot a plane and world x, y)")
    add_json(p)
    add_strict(p)
    add_config_options(p)
    return p


def _turn_invariant(args):
    """--turn-invariant: a shortcut for --set classifier.turn_invariant=true."""
    return shortcut("classifier.turn_invariant", True) if args.turn_invariant else None


def _train_kinds(args) -> tuple:
    """evaluate --train-kinds as a tuple, refused unless generated and/or training kinds."""
    from ..objects.placement_kinds import TRAINING_KINDS
    kinds = tuple(k.strip() for k in args.train_kinds.split(",") if k.strip())
    bad = set(kinds) - {"generated", *TRAINING_KINDS}
    if bad or not kinds:
        raise UserError(f"--train-kinds must name generated and/or "
                        f"{' / '.join(TRAINING_KINDS)}, got {args.train_kinds!r}")
    return kinds


def _evaluate_placed(args, objects, cfg) -> dict:
    """evaluate --placed: chords and triangles on placed copies; writes OUT/placements.*"""
    from pathlib import Path

    from ..files import write_atomic, write_json
    from ..learning.placements import evaluate_placements, placements_table
    kinds = _train_kinds(args)
    records = list(objects)
    for folder in args.placed:
        records += load_objects(folder, cfg.chords, args.strict)[0]
    results = {m: evaluate_placements(records, args.splits, args.seed, method=m,
                                      params=cfg.classifier, train_kinds=kinds)
               for m in ("chords", "triangles")}
    out = Path(args.out)
    table = placements_table(results)
    write_atomic(out / "placements.md", table.encode())
    write_json(out / "placements.json", results)
    return {"table": table, "results": results}


def _run_evaluate(args):
    from ..learning.evaluation import evaluate_to_folder
    if args.splits < 1:
        raise UserError(f"--splits must be at least 1, got {args.splits}")
    if args.placed:
        _train_kinds(args)  # refused before the evaluation, not after it
    check_out_apart(args, "the evaluation")
    cfg = command_config(args, shortcut("chords.frame", args.frame), _turn_invariant(args),
                  uses=("chords", "classifier"))
    objects, skipped = load_objects(args.wraps, cfg.chords, args.strict)
    check_categories(objects, 4, "a 50/50 split by object leaves 2 to train on")
    summary = evaluate_to_folder(objects, args.out, n_splits=args.splits, seed=args.seed,
                                 params=cfg.classifier, skipped=skipped,
                                 progress=not args.quiet)
    del summary["table1"]
    summary["out"] = str(args.out)
    placed = _evaluate_placed(args, objects, cfg) if args.placed else None
    if placed:
        summary["placements"] = {
            m: {"kinds": {k: v["accuracy_mean"] for k, v in r["kinds"].items()},
                "flip_rate": r["flips"]["rate"]} for m, r in placed["results"].items()}
    if args.json:
        print_json(summary)
    else:
        print(f"{len(objects)} objects, {args.splits} splits: chords "
              f"{summary['accuracy_mean']:.1%} +- {summary['accuracy_std']:.1%}, triangles "
              f"{summary['baseline_accuracy_mean']:.1%} +- "
              f"{summary['baseline_accuracy_std']:.1%}; wrote {args.out}")
        if skipped:
            print(f"left out {len(skipped)} object(s) of the collection (listed in "
                  f"evaluation.json): {', '.join(s['object_id'] for s in skipped)}")
        wrong = summary["misclassified"]
        if wrong:
            print(f"most often wrong (of {len(wrong)} ever wrong; all in evaluation.json):")
            for r in wrong[:5]:
                taken = ", ".join(f"{c} {n}" for c, n in r["as"].items())
                print(f"  {r['object_id']} ({r['category']}): wrong {r['wrong']} of "
                      f"{r['tested']} (as {taken})")
            print(f"see one: drake-continuum show-wraps {args.wraps} "
                  f"{wrong[0]['object_id']} --png wraps.png")
        if placed:
            print(f"placed objects ({args.splits} splits by object; {args.out}/placements.md):")
            print(placed["table"], end="")
    return 0


def _add_train(subparsers):
    p = subparsers.add_parser(
        "train", help="train the chord classifier on every object and save it",
        description="Fit the chord-histogram classifier on all objects of a wrap collection "
                    "and save it as model.json + model.npz (no pickle). "
                    "Example: drake-continuum train data/wraps --out models/classifier")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--out", required=True, help="model folder to write, required")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--frame", choices=["world", "wrap", "upright", "plane"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="also train on these collections' placed copies of the training "
                        "kinds, train and side (`objects place --placements side=3`, then "
                        "collect; repeatable; default: none)")
    p.add_argument("--turn-invariant", action="store_true",
                   help="wrap descriptors pooled over planes, contact extent along the "
                        "contacts' own horizontal axes, a shortcut for --set "
                        "classifier.turn_invariant=true (default: the configuration's, off)")
    _add_touch_only(p)
    add_json(p)
    add_strict(p)
    add_config_options(p)
    return p


def _add_touch_only(p):
    p.add_argument("--touch-only", action="store_true",
                   help="leave out the feature blocks that need the object visible (the "
                        "depth camera's view of it): the model for transparent objects, a "
                        "shortcut for --set classifier.view_weight=0 (default: off)")


def _touch_only(args):
    """--touch-only: a shortcut for --set classifier.view_weight=0."""
    return shortcut("classifier.view_weight", 0.0) if args.touch_only else None


def _run_train(args):
    from ..experiments.collection import training_settings
    from ..learning.model import save_model, train
    from ..objects.placement_kinds import TRAINING_KINDS, placement_kind
    # The arm, planes and wrap settings are the collection's (training_settings).
    cfg = command_config(args, shortcut("chords.frame", args.frame), _turn_invariant(args),
                  _touch_only(args), uses=("chords", "classifier"))
    check_out_apart(args)
    settings = training_settings(cfg, args.wraps)
    objects, skipped = load_objects(args.wraps, cfg.chords, args.strict)
    for folder in args.placed:
        more, also = load_objects(folder, cfg.chords, args.strict)
        objects += [o for o in more if placement_kind(o.object_id) in TRAINING_KINDS]
        skipped += also
    check_categories(objects, 2, "the classifier trains on 2 or more a category")
    model = train(objects, cfg, seed=args.seed)
    model.info["settings"] = settings
    save_model(model, args.out)
    summary = {"model": str(args.out), "classes": list(model.classes),
               **{k: v for k, v in model.info.items() if k != "settings"}, "skipped": skipped}
    if args.json:
        print_json(summary)
    else:
        print(f"trained on {len(objects)} objects of {len(model.classes)} categories "
              f"({', '.join(map(str, model.classes))}); wrote {args.out}")
        if model.standing is not None:
            print(f"with a model of the {model.info['n_standing_objects']} standing objects "
                  f"alone, mixed in by the probability of lying on another side "
                  f"(classifier.standing_model)")
        if skipped:
            print(f"left out {len(skipped)} object(s): "
                  f"{', '.join(s['object_id'] for s in skipped)}")
    return 0


def _add_show_wraps(subparsers):
    p = subparsers.add_parser(
        "show-wraps", help="draw the stored wraps of one object of a collection",
        description="Draw every usable wrap that `collect` stored for OBJECT_ID on its mesh, "
                    "one cell a plane (e.g. an object `evaluate` lists as often wrong). The "
                    "mesh is found in the collection's dataset, or in --dataset, and must be "
                    "the one wrapped (same SHA-256). "
                    "Example: drake-continuum show-wraps results-full/wraps donut_003 --png "
                    "donut_003.png")
    p.add_argument("wraps", help="wrap collection folder (drake-continuum collect), required")
    p.add_argument("object_id", help="object to draw, e.g. bowl_003, required")
    p.add_argument("--png", required=True, help="picture to write, required")
    p.add_argument("--dataset", default=None,
                   help="folder holding the object's mesh (default: the collection's dataset "
                        "as recorded in its index.json)")
    add_json(p)
    return p


def _run_show_wraps(args):
    import yaml

    from ..experiments.collect import wrapped_mesh_path
    from ..kinematics.arm import ContinuumArm, load_arm
    from ..learning.records import WrapFileError, read_object_wraps
    from ..objects.mesh import load_mesh
    from ..viz.plots import plot_object_wraps
    try:
        meta, wraps = read_object_wraps(args.wraps, args.object_id)
    except WrapFileError as e:
        raise UserError(f"{args.object_id}: {e}") from None
    try:
        mesh = load_mesh(wrapped_mesh_path(args.wraps, args.object_id, meta, dataset=args.dataset))
    except (OSError, ValueError) as e:  # MeshError is a ValueError
        raise UserError(str(e)) from None
    usable = [w for w in wraps if w.usable]
    if not usable:
        raise UserError(f"{args.object_id}: none of its {len(wraps)} wraps is usable "
                        f"(statuses: {', '.join(sorted({w.status for w in wraps}))})")
    n = len(usable)
    arm_yaml = (meta.get("params") or {}).get("arm_yaml")  # the arm the wraps were made with
    arm = load_arm() if arm_yaml is None else ContinuumArm.from_dict(yaml.safe_load(arm_yaml))
    png = plot_object_wraps(mesh, arm, usable, path=args.png)
    out = {"object_id": args.object_id, "category": meta.get("category"),
           "n_wraps": len(wraps), "n_usable": n, "planes": [w.plane_index for w in usable],
           "png": str(png)}
    if args.json:
        print_json(out)
    else:
        print(f"{args.object_id} ({out['category']}): {n} of {len(wraps)} wraps drawn in {png}")
    return 0


def _add_classify(subparsers):
    p = subparsers.add_parser(
        "classify", help="wrap a new mesh on every plane and classify it",
        description="Wrap OBJECT_MESH where it stands in world coordinates (or set down "
                    "by --rest-pose/--turn/--offset) on every wrap plane, the arm lined up on "
                    "a position a robot would have (--position, or the simulated depth "
                    "camera's estimate; never the mesh's own geometry, never its "
                    "orientation), and classify its wraps with a trained model. "
                    "Example: drake-continuum classify results/model models/mug.obj --turn 90 "
                    "--json --png mug_wraps.png")
    p.add_argument("model", help="trained model folder (drake-continuum train), required")
    p.add_argument("mesh", help="object mesh (OBJ, STL, PLY, OFF), required")
    add_placed_mesh_options(p)
    add_json(p)
    p.add_argument("--png", default=None,
                   help="also draw every usable wrap on the mesh, one cell a plane, to this "
                        "PNG (default: none)")
    add_observe_options(p)
    add_simplify(p)
    add_config_options(p, "the settings the model records, its training collection's")
    return p


def _run_classify(args):
    import dataclasses

    from ..learning.model import classify, load_model
    from ..wrapping.wrap import wrap
    model = load_model(args.model)
    observe = observe_options(args, model)
    cfg = saved_model_config(args, model.info)
    arm = cfg.arm()
    planes = config_planes(cfg, arm)
    # Every plane: the model's wrap descriptors are kept a plane, as in training.
    if len(planes) < model.n_planes:
        raise UserError(f"{args.model}: the model knows {model.n_planes} wrap planes, the "
                        f"configuration gives {len(planes)}")
    scene, _, position = placed_scene(args, arm, cfg.bearing)
    wraps = [wrap(scene, p, cfg.wrap) for p in planes]
    if not any(w.usable for w in wraps):
        raise UserError(f"{args.mesh}: no wrap plane touched the object")
    seen = None
    if observe is not None:
        from ..perception.observe import observe_wraps
        seen = observe_wraps(wraps, arm, scene.object_trimesh, **observe)
        wraps = [o.wrap for o in seen]
        if not any(w.usable for w in wraps):
            raise UserError(f"{args.mesh}: the camera found the arm in none of the wraps")
    result = classify(model, wraps, None if args.transparent else position["view"])
    out = {**dataclasses.asdict(result), "position": position, "observe": args.observe,
           "transparent": args.transparent}
    if seen is not None:
        out["observations"] = [o.to_dict() for o in seen]
    if args.png:
        from ..viz.plots import plot_object_wraps
        out["png"] = str(plot_object_wraps(scene.object_trimesh, arm,
                                           [w for w in wraps if w.usable], path=args.png))
    if args.json:
        print_json(out)
    else:
        print(f"{args.mesh}: {result.category} (p = "
              f"{result.probabilities[result.category]:.2f}, {result.n_wraps} wraps)")
        if seen is not None:
            print(f"seen by the camera: {observation_summary(out['observations'])}")
        if args.png:
            print(f"wraps drawn in {out['png']}")
    return 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("evaluate", _add_evaluate, _run_evaluate),
    ("train", _add_train, _run_train),
    ("show-wraps", _add_show_wraps, _run_show_wraps),
    ("classify", _add_classify, _run_classify),
]
