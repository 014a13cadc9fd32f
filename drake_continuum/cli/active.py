"""`train-active`, `evaluate-active`, `recognize`: active recognition.
"""

from __future__ import annotations

from .common import (
    UserError,
    add_config_options,
    add_json,
    add_meshcat,
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
    serve_meshcat,
    shortcut,
)

__all__ = ["COMMANDS"]


def _active_config(args):
    return command_config(args, shortcut("active.seed", args.seed),
                   shortcut("active.n_simulations", args.simulations),
                   shortcut("chords.frame", args.frame),
                   shortcut("classifier.view_weight",
                             0.0 if getattr(args, "touch_only", False) else None),
                   uses=("chords", "classifier", "active"))


def _add_active_options(p):
    p.add_argument("--seed", type=int, default=None,
                   help="random seed of the split, classifier and searches, a shortcut for "
                        "--set active.seed=... (default: the configuration's, 0)")
    p.add_argument("--simulations", type=int, default=None,
                   help="simulations a tree search, a shortcut for --set "
                        "active.n_simulations=... (default: the configuration's, 200)")
    p.add_argument("--frame", choices=["world", "wrap", "upright", "plane"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    add_strict(p)
    add_config_options(p)


def _add_train_active(subparsers):
    p = subparsers.add_parser(
        "train-active", help="train the classifier and the observation tallies for recognition",
        description="Fit the chord classifier on every object of a wrap collection and tally "
                    "its wraps for active recognition (section IV-D.2); save both in one "
                    "folder (model.json/.npz, observations.json/.npz; no pickle). "
                    "Example: drake-continuum train-active data/wraps --out models/active")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--out", required=True, help="model folder to write, required")
    p.add_argument("--touch-only", action="store_true",
                   help="leave out the feature blocks that need the object visible (the "
                        "depth camera's view of it): the model for transparent objects, a "
                        "shortcut for --set classifier.view_weight=0 (default: off)")
    p.add_argument("--class-prior", choices=["training", "uniform"], default="training",
                   help="what recognition assumes of a category before the first wrap: as "
                        "frequent as among the training objects, or every category alike "
                        "(for objects that come N a category; default: training)")
    add_json(p)
    _add_active_options(p)
    return p


def _run_train_active(args):
    from ..active.training import save_active_model, train_active
    from ..experiments.collection import training_settings
    cfg = _active_config(args)
    check_out_apart(args)
    settings = training_settings(cfg, args.wraps)
    objects, skipped = load_objects(args.wraps, cfg.chords, args.strict)
    check_categories(objects, 2, "the classifier trains on 2 or more a category")
    model = train_active(args.wraps, cfg, seed=cfg.active.seed, records=objects,
                         class_prior=args.class_prior)
    model.classifier.info["settings"] = settings
    save_active_model(model, args.out)
    obs = model.observations
    summary = {"model": str(args.out), "classes": [str(c) for c in obs.classes],
               "n_observations": obs.n_observations, "n_pairs": int(len(obs.pair_from)),
               "n_planes": obs.n_planes, "skipped": skipped}
    if args.json:
        print_json(summary)
    else:
        print(f"trained on {len(objects)} objects of {len(obs.classes)} categories; "
              f"{obs.n_observations} observations over {obs.n_planes} planes; wrote {args.out}")
        if skipped:
            print(f"left out {len(skipped)} object(s): "
                  f"{', '.join(s['object_id'] for s in skipped)}")
    return 0


def _add_evaluate_active(subparsers):
    p = subparsers.add_parser(
        "evaluate-active", help="active recognition on held-out objects: MCTS vs baselines",
        description="Train on one half of a stratified split of a wrap collection and "
                    "recognise every held-out object from its precomputed wraps with tree "
                    "search (MCTS), greedy information gain and random plane order; write "
                    "active.json, accuracy curves (curves.png) and Table II (table2.md). "
                    "Example: drake-continuum evaluate-active data/wraps --out results/active")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--policy", choices=["mcts", "greedy", "random", "all"], default="all",
                   help="policy to evaluate (default: all)")
    p.add_argument("--out", default="results/active",
                   help="output folder (default: results/active)")
    add_json(p)
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="test on the held-out objects' placed copies (turned, on another "
                        "side, nudged) from this collection of `objects place` output "
                        "(repeatable), splitting by object (default: the originals)")
    p.add_argument("--train-kinds", default="generated",
                   help="with --placed, the records trained on: generated and/or the "
                        "training placements train and side (default: generated)")
    p.add_argument("--test", action="append", default=[], metavar="WRAPS",
                   help="test on every object of this collection of another dataset (e.g. "
                        "another seed's originals or placed copies; repeatable) instead of "
                        "the held-out half (default: the held-out half)")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes running the recognitions (default: all cores)")
    _add_active_options(p)
    return p


def _run_evaluate_active(args):
    from ..active.policies import POLICIES
    from ..active.training import evaluate_active
    cfg = _active_config(args)
    objects, _ = load_objects(args.wraps, cfg.chords, args.strict)
    check_categories(objects, 2, "the classifier trains on 2 or more a category")
    policies = POLICIES if args.policy == "all" else (args.policy,)
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    from ..objects.placement_kinds import TRAINING_KINDS
    kinds = tuple(k.strip() for k in args.train_kinds.split(",") if k.strip())
    if not kinds or set(kinds) - {"generated", *TRAINING_KINDS}:
        raise UserError(f"--train-kinds must name generated and/or "
                        f"{' / '.join(TRAINING_KINDS)}, got {args.train_kinds!r}")
    check_out_apart(args, "the evaluation")
    report = evaluate_active(args.wraps, policies=policies, params=cfg.active,
                             seed=cfg.active.seed, chords=cfg.chords,
                             classifier=cfg.classifier, out=args.out, placed=args.placed,
                             train_kinds=kinds, test=args.test, workers=args.workers)
    summary = {"n_train": report["n_train"], "n_test": report["n_test"], "out": str(args.out),
               "skipped": report["skipped"],
               "policies": {k: {m: v[m] for m in ("accuracy_at_stop", "wraps_to_stop",
                                                  "movement_cost_to_stop_rad",
                                                  "median_search_time_s", "by_kind")
                                if m in v}
                            for k, v in report["policies"].items()}}
    if args.json:
        print_json(summary)
    else:
        for k, v in summary["policies"].items():
            kinds = "".join(f", {q} {a:.1%}" for q, a in v.get("by_kind", {}).items())
            print(f"{k}: accuracy {v['accuracy_at_stop']:.1%} after {v['wraps_to_stop']:.2f} "
                  f"wraps, movement {v['movement_cost_to_stop_rad']:.2f} rad{kinds}")
        print(f"wrote {args.out}")
    return 0


def _add_recognize(subparsers):
    p = subparsers.add_parser(
        "recognize", help="active recognition of a mesh: tree search chooses the wraps",
        description="Recognise OBJECT_MESH by active wrapping (section IV-D): each iteration "
                    "a Monte Carlo tree search plans the next wraps, they are made in "
                    "simulation, and the accumulated chords are classified, until the "
                    "strong-prediction rule or the iteration limit. The mesh stands where "
                    "its world coordinates put it (or is set down by --rest-pose/--turn/"
                    "--offset); the arm is lined up on --position or the depth camera's "
                    "estimate. "
                    "Example: drake-continuum recognize results/active-model models/mug.obj "
                    "--turn 45")
    p.add_argument("model", help="model folder from `drake-continuum train-active`, required")
    p.add_argument("mesh", help="object mesh (OBJ, STL, PLY, OFF), required")
    add_placed_mesh_options(p)
    p.add_argument("--seed", type=int, default=None,
                   help="seed, a shortcut for --set active.seed=... (default: the "
                        "configuration's)")
    add_json(p)
    add_meshcat(p, "the last wrap")
    p.add_argument("--html", default=None, help="save the animation as a page (default: none)")
    add_observe_options(p)
    add_simplify(p)
    add_config_options(p, "the settings the model records, its training collection's")
    return p


def _run_recognize(args):
    from ..active.policies import recognize, simulated_execute
    from ..active.training import load_active_model
    model = load_active_model(args.model)
    observe = observe_options(args, model.classifier)
    if args.seed is not None:
        args.set = [f"active.seed={args.seed}"] + list(args.set)
    cfg = saved_model_config(args, model.classifier.info)
    arm = cfg.arm()
    known = model.observations.n_planes
    planes = config_planes(cfg, arm)
    if known > len(planes):  # a model of fewer planes (the first ones) is served by these
        raise UserError(f"{args.model}: the model knows {known} wrap planes; the "
                        f"configuration gives {len(planes)} (alpha = {cfg.alpha_deg} deg)")
    scene, _, position = placed_scene(args, arm, cfg.bearing)
    done, seen = [], None
    if observe is None:
        execute = simulated_execute(scene, planes, model.classifier.chord_params,
                                    wrap_params=cfg.wrap,
                                    log=done)
    else:
        from ..perception.observe import observed_execute
        seen = []
        execute = observed_execute(scene, planes, model.classifier.chord_params, cfg.wrap,
                                   log=seen, **observe)
    out = recognize(model, execute, cfg, view=None if args.transparent else position["view"])
    if seen is not None:
        done = [o.wrap for o in seen]
    if args.meshcat or args.html:
        from ..viz.meshcat import show_wrap
        configs = [c for w in done for c in w.configs] or [scene.config]
        last = done[-1] if done else None
        meshcat, _ = show_wrap(last.arm(arm) if last else arm,
                               scene.object_trimesh, [c for c in last.configs] if last else configs,
                               contacts=last.contacts if last else None, html_path=args.html)
    url = {"meshcat_url": meshcat.web_url()} if args.meshcat else {}
    with serve_meshcat(args):  # the URL, then serving: one Ctrl-C-safe block
        if args.json:
            extra = {"observe": args.observe, "transparent": args.transparent}
            if seen is not None:
                extra["observations"] = [o.to_dict() for o in seen]
            print_json({**out.to_dict(), "position": position, **extra, **url})
        else:
            for k, it in enumerate(out.iterations, 1):
                top = ", ".join(f"{c} {p:.2f}" for c, p in it.top3)
                print(f"iteration {k}: {it.n_wraps} wraps, movement {it.movement_cost:.2f} "
                      f"rad: {top}")
            print(f"{args.mesh}: {out.category} ({out.stopped_because})")
            if seen is not None:
                print(f"seen by the camera: "
                      f"{observation_summary([o.to_dict() for o in seen])}")
            if url:
                print(f"Meshcat: {url['meshcat_url']}")
    return 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("train-active", _add_train_active, _run_train_active),
    ("evaluate-active", _add_evaluate_active, _run_evaluate_active),
    ("recognize", _add_recognize, _run_recognize),
]
