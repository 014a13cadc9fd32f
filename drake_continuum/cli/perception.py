"""`fit-cloud`, `compare-real`, `simulate-cloud`, `classify-captures`: point clouds of the
real robot.
"""

from __future__ import annotations

from .common import (
    UserError,
    add_config_options,
    add_json,
    command_config,
    config_planes,
    old_spelling,
    parse_floats,
    print_json,
    read_arm_config,
    saved_model_config,
    shortcut,
)

__all__ = ["COMMANDS"]


# ----------------------------------------------------------------- point clouds (real robot)
def _add_cloud_options(p):
    p.add_argument("--arm", default=None,
                   help="arm description YAML, a shortcut for --set arm=FILE (default: the "
                        "configuration's, models/arm.yaml)")
    add_config_options(p)
    p.add_argument("--base-pose", dest="base_pose", default=None,
                   help="arm base pose x,y,z,roll,pitch,yaw (m, rad) in the cloud's frame, e.g. "
                        "-0.18,0,0.05,0,1.5708,0 (default: the cloud's sidecar CLOUD.json if "
                        "it has one, else the arm YAML's)")
    p.add_argument("--lengths", default=None,
                   help="known section lengths s1,s2,s3 in m, e.g. 0.15,0.2,0.2, or 'free' to "
                        "fit them (default: the commanded lengths of the sidecar CLOUD.json's "
                        "config if it has one, else fitted)")
    p.add_argument("--units", choices=["auto", "m", "mm"], default="auto",
                   help="units of the cloud file (default: auto, millimetres when it spans "
                        "more than 20 units)")
    p.add_argument("--no-colour", dest="no_colour", action="store_true",
                   help="segment by geometry alone, for an arm not painted the arm colour "
                        "(default: colour gate on)")
    p.add_argument("--drop-nan", dest="drop_nan", action="store_true",
                   help="discard NaN/infinite points (organised clouds) instead of failing "
                        "(default: fail)")
    p.add_argument("--camera", action="append", default=None,
                   help="camera position x,y,z (m) in the cloud's frame, once a cloud in their "
                        "order, e.g. 0.3,-0.5,0.85; what it saw through is evidence of where the "
                        "arm is not (default: the camera in each cloud's sidecar CLOUD.json if "
                        "it has one, else none)")
    p.add_argument("--prior", default=None,
                   help='the commanded configuration, a JSON file or text {"s":[..],"kappa":[..],'
                        '"phi":[..]} (or a sidecar holding one under "config"), which the fit '
                        "stays near where points do not decide (default: none)")
    p.add_argument("--plane-normal", dest="plane_normal", default=None,
                   help="the normal nx,ny,nz of the plane the wrap was commanded in, in the "
                        "cloud's frame: it holds the sections the camera did not see in that "
                        "plane (default: none)")
    p.add_argument("--prior-sigma", dest="prior_sigma", default="0.01,1.0,0.2",
                   help="the prior's standard deviations: section length (m), curvature (1/m), "
                        "bending direction (rad) (default: 0.01,1.0,0.2)")
    add_json(p)
    p.add_argument("--png", default=None,
                   help="draw cloud, segmented arm and reconstruction (the paper's Fig. 8) to "
                        "this PNG, e.g. out/fig8.png (default: none)")
    old_spelling(p, "--base_pose", "base_pose")
    old_spelling(p, "--no_colour", "no_colour", action="store_true")
    old_spelling(p, "--drop_nan", "drop_nan", action="store_true")
    old_spelling(p, "--prior_sigma", "prior_sigma")



def _cloud_arm_and_fit(args):
    """(cloud, arm, segmentation, fit, base source, prior, lengths source) for the point-cloud
    commands; with several clouds (views of one wrap) the cloud returned is the first."""

    import numpy as np
    from pydrake.math import RollPitchYaw

    from ..perception.cloud import (
        PointCloudError,
        load_cloud,
        sidecar_base,
        sidecar_eyes,
        sidecar_lengths,
    )
    from ..perception.fitting import fit_cloud
    from ..perception.residuals import ConfigPrior, WrapPlane
    from ..perception.segmentation import SegmentParams
    arm = command_config(args, shortcut("arm", args.arm), uses=("arm",)).arm()
    clouds = [load_cloud(c, units=args.units, drop_nonfinite=args.drop_nan)
              for c in args.cloud]
    cloud = clouds[0]
    base_from = "arm description"
    recorded = sidecar_base(args.cloud)  # checked even with --base-pose: views of one wrap
    if args.base_pose is not None:
        v = parse_floats(args.base_pose, 6, "--base-pose")
        arm = arm.with_base(np.array(v[:3]), RollPitchYaw(v[3:]).ToRotationMatrix().matrix())
        base_from = "--base-pose"
    elif recorded is not None:
        position, rpy, sidecar = recorded
        arm = arm.with_base(position, RollPitchYaw(rpy).ToRotationMatrix().matrix())
        base_from = str(sidecar)
    lengths, lengths_from = None, "fitted"
    if args.lengths is None:
        recorded = sidecar_lengths(args.cloud, arm.n_sections)
        if recorded is not None:
            lengths, lengths_from = recorded[0].tolist(), str(recorded[1])
    elif args.lengths.strip().lower() != "free":
        lengths = parse_floats(args.lengths, arm.n_sections, "--lengths")
        lengths_from = "--lengths"
    if lengths is not None:
        for i, (s, lo, hi) in enumerate(zip(lengths, *arm.section_limits()[:2])):
            if not lo <= s <= hi:
                raise UserError(f"{lengths_from}: section {i + 1} must lie in [{lo:g}, "
                                f"{hi:g}] m, got {lengths}")
    if args.camera is not None:
        if len(args.camera) != len(clouds):
            raise UserError(f"--camera given {len(args.camera)} times for {len(clouds)} "
                            f"cloud(s): give one camera position a cloud, in their order")
        eyes = [np.array(parse_floats(c, 3, "--camera")) for c in args.camera]
    else:
        eyes = sidecar_eyes(args.cloud)
    prior = None
    if args.prior is not None:
        sig = parse_floats(args.prior_sigma, 3, "--prior-sigma")
        config = read_arm_config(args.prior, "--prior")
        try:
            arm.check(config)
            prior = ConfigPrior(config, *sig)
        except ValueError as e:
            raise UserError(f"--prior: {e}") from None
    seg_params = SegmentParams(colour=None) if args.no_colour else SegmentParams()
    plane = None
    if args.plane_normal is not None:
        try:
            plane = WrapPlane(tuple(parse_floats(args.plane_normal, 3, "--plane-normal")))
        except PointCloudError as e:
            raise UserError(f"--plane-normal: {e}") from None
    seg, fit = fit_cloud(clouds, arm, lengths, seg_params, eye=eyes, prior=prior, plane=plane)
    return cloud, arm, seg, fit, base_from, prior, lengths_from


def _print_fit(fit, seg, cloud, *, base_from, lengths_from):
    import numpy as np
    d = fit.to_dict()
    print(f"{cloud.source}: {seg.n_input} points ({cloud.units}), arm {len(seg.points)} points "
          f"in {seg.n_pieces} piece(s); base pose from {base_from}; section lengths "
          f"{'fitted' if lengths_from == 'fitted' else 'known, from ' + lengths_from}")
    for i in range(fit.config.n_sections):
        print(f"  section {i + 1}: s = {fit.config.s[i]:.4f} m, kappa = "
              f"{fit.config.kappa[i]:.3f} 1/m, phi = {np.degrees(fit.config.phi[i]):.1f} deg")
    r = d["residual"]
    print(f"  tip at {np.round(fit.tip, 4).tolist()} m; residual mean {r['mean_abs_mm']:.2f} mm, "
          f"median {r['median_abs_mm']:.2f} mm, p95 {r['p95_abs_mm']:.2f} mm, max "
          f"{r['max_abs_mm']:.2f} mm, inliers {100 * r['inlier_fraction']:.0f} %; "
          f"{fit.time_s:.2f} s")
    if not fit.unseen:
        print("  unseen: none (points along the whole arm)")
    for u in d["unseen"]:
        print(f"  unseen: arc length {u['from_m']:.3f} to {u['to_m']:.3f} m "
              f"(section {', '.join(map(str, u['sections']))})")
    c = fit.confidence
    if c is not None:
        seen = ", ".join(f"{100 * f:.0f} %" for f in c.seen_fraction)
        free = "no camera position" if c.free_space_rays is None else \
            f"{c.free_space_rays} rays seen through the fitted arm"
        more = "; the arm may continue unseen past its last seen point" \
            if c.tip_may_continue else ""
        print(f"  seen per section: {seen}; free space: {free}{more}")
        print(f"  tip uncertainty {1e3 * c.tip_uncertainty:.1f} mm (sigma {1e3 * c.tip_sigma:.1f}"
              f" mm, spread {1e3 * c.tip_spread:.1f} mm over {c.n_solutions} distinct "
              f"solution(s)): {c.verdict}")


def _add_fit_cloud(subparsers):
    p = subparsers.add_parser(
        "fit-cloud", help="fit the arm's configuration to a depth-camera point cloud",
        description="Segment the arm (painted orange) from a .pcd/.ply cloud in the world "
                    "frame and fit every section's length, curvature and bending angle. "
                    "Example: drake-continuum fit-cloud real/data/cylinder_0.pcd --png "
                    "out/fit.png")
    p.add_argument("cloud", nargs="+",
                   help="point cloud .pcd or .ply; several for views of one wrap from different "
                        "cameras (required)")
    _add_cloud_options(p)
    return p


def _run_fit_cloud(args):
    from ..perception.comparison import fig8
    cloud, arm, seg, fit, base_from, prior, lengths_from = _cloud_arm_and_fit(args)
    out = {"cloud": cloud.source, "clouds": list(args.cloud), "units": cloud.units,
           "base_from": base_from, "lengths_from": lengths_from,
           "prior": None if prior is None else prior.to_dict(),
           "n_points": seg.n_input, "arm_points": len(seg.points), "pieces": seg.n_pieces,
           **fit.to_dict()}
    if args.png:
        out["png"] = str(fig8(args.png, cloud, seg, fit, arm, title=cloud.source))
    if args.json:
        print_json(out)
    else:
        _print_fit(fit, seg, cloud, base_from=base_from, lengths_from=lengths_from)
        if args.png:
            print(f"wrote {out['png']}")
    return 0


def _add_compare_real(subparsers):
    p = subparsers.add_parser(
        "compare-real", help="compare a real wrap (point cloud) with its simulated version",
        description="Fit the arm to the cloud, rebuild it in the Drake contact scene at that "
                    "configuration against the object, and report per-point deviation, the "
                    "chord-histogram distance between the two wraps and, with --model, the "
                    "category each yields (the paper's section V-D). Example: drake-continuum "
                    "compare-real real/data/cylinder_0.pcd --object real/data/cylinder.obj "
                    "--png out/fig8.png")
    p.add_argument("cloud", nargs="+",
                   help="point cloud .pcd or .ply; several for views of one wrap from different "
                        "cameras (required)")
    p.add_argument("--force", action="store_true",
                   help="call categories even from an ambiguous fit (default: refuse)")
    p.add_argument("--object", required=True,
                   help="object mesh in the world frame, e.g. real/data/cylinder.obj (required)")
    p.add_argument("--model", default=None,
                   help="trained model folder (drake-continuum train), e.g. out/model "
                        "(default: none, no categories)")
    _add_cloud_options(p)
    return p


def _run_compare_real(args):
    from ..perception.comparison import compare_real
    model = None
    if args.model is not None:
        from ..learning.model import load_model
        model = load_model(args.model)
    cloud, arm, seg, fit, base_from, prior, lengths_from = _cloud_arm_and_fit(args)
    c = fit.confidence
    if model is not None and c is not None and c.ambiguous and not args.force:
        raise UserError(f"{cloud.source}: the fit is ambiguous (tip uncertainty "
                        f"{1e3 * c.tip_uncertainty:.0f} mm, {c.n_solutions} distinct solutions "
                        f"explain the points; seen per section "
                        f"{', '.join(f'{100 * f:.0f} %' for f in c.seen_fraction)}), so no "
                        f"category is called from it: add a view from another side, give "
                        f"--prior, or pass --force")
    out = compare_real(cloud, seg, fit, arm, args.object, model, args.png,
                          simulated=None if prior is None else prior.config)
    out["base_from"], out["lengths_from"] = base_from, lengths_from
    out["forced"] = bool(model is not None and c is not None and c.ambiguous)
    dev = out["deviation"]
    if args.json:
        print_json(out)
        return 0
    _print_fit(fit, seg, cloud, base_from=base_from, lengths_from=lengths_from)
    print(f"real vs simulated: deviation mean {dev['mean_mm']:.2f} mm, Hausdorff "
          f"{dev['hausdorff_mm']:.2f} mm")
    ch = out["chords"]
    if ch.get("histogram_distance") is None:
        print(f"chord histograms: not compared ({ch.get('note')})")
    else:
        print(f"chord histograms: distance {ch['histogram_distance']:.3f} (total variation; "
              f"{ch['n_chords_real']} real, {ch['n_chords_simulated']} simulated chords)")
    if "category_real" in ch:
        forced = " (from an ambiguous fit: --force)" if out["forced"] else ""
        print(f"category: real {ch['category_real']}, simulated {ch['category_simulated']}"
              f"{forced}")
    if args.png:
        print(f"wrote {out['png']}")
    return 0


def _add_simulate_cloud(subparsers):
    p = subparsers.add_parser(
        "simulate-cloud", help="render a Kinect-like point cloud of the arm around an object",
        description="Render the arm (at a configuration, or at the end of a wrap on a plane) "
                    "against the object on the table with a Kinect v1 error model and write "
                    "the world-frame cloud plus a JSON sidecar with the true configuration. "
                    "The wrap treats the table top as an obstacle, as a real arm over a table "
                    "must (--set wrap.table=false: through it, as the classification wraps). "
                    "Example: drake-continuum simulate-cloud models/mug.obj --plane 1 --out "
                    "out/mug.pcd")
    p.add_argument("object", help="object mesh in the world frame (required)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--plane", type=int, default=None,
                       help="wrap on this default plane and render its final configuration "
                            "(default: none)")
    which.add_argument("--arm-config", dest="arm_config", default=None,
                       help='arm configuration to render, JSON file or text {"s":[..],'
                            '"kappa":[..],"phi":[..]} (default: none)')
    p.add_argument("--out", default="cloud.pcd",
                   help="output cloud .pcd or .ply; the sidecar is OUT with .json (default: "
                        "cloud.pcd)")
    p.add_argument("--deform", type=float, default=0.0,
                   help="how far the tube flattens against the object at contacts, mm "
                        "(default: 0)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default: 0)")
    p.add_argument("--voxel", type=float, default=0.0,
                   help="voxel downsampling of the written cloud, m, e.g. 0.004 (default: 0, "
                        "every pixel)")
    p.add_argument("--cameras", type=int, default=1,
                   help="views of the wrap: N cameras at the default camera's height and "
                        "distance, spread evenly round the object (2: the second opposite the "
                        "first); with N > 1 the clouds are OUT_view0 ... OUT_view<N-1> "
                        "(default: 1)")
    p.add_argument("--arm", default=None,
                   help="arm description YAML, a shortcut for --set arm=FILE (default: the "
                        "configuration's, models/arm.yaml)")
    old_spelling(which, "--arm_config", "arm_config")
    add_json(p)
    add_config_options(p)
    return p


def _run_simulate_cloud(args):
    from ..objects.mesh import load_mesh
    from ..perception.depth_camera import simulate_clouds
    # A real arm over a table can only make wraps that stay above it: the cloud to compare
    # with one comes from such a wrap (the paper's classification wraps ignore the table);
    # --set wrap.table=false overrides.
    cfg = command_config(args, shortcut("arm", args.arm), defaults=("wrap.table=true",))
    arm = cfg.arm()
    mesh = load_mesh(args.object)
    if args.deform < 0:
        raise UserError(f"--deform must be >= 0 mm, got {args.deform}")
    if args.cameras < 1:
        raise UserError(f"--cameras must be at least 1, got {args.cameras}")
    if not args.out.lower().endswith((".pcd", ".ply")):
        raise UserError(f"--out must end in .pcd or .ply, got {args.out}")
    meta = {"object": str(args.object)}
    if args.arm_config is not None:
        config = read_arm_config(args.arm_config, "--arm-config")
        arm.check(config)
    else:
        from ..wrapping.scene import WrapScene
        from ..wrapping.wrap import wrap
        planes = config_planes(cfg, arm)
        if not 0 <= args.plane < len(planes):
            raise UserError(f"--plane must lie in 0..{len(planes) - 1}, got {args.plane}")
        result = wrap(WrapScene(arm, args.object), planes[args.plane], cfg.wrap)
        config = result.final_config
        arm = result.arm(arm)
        meta.update(plane=args.plane, wrap_status=result.status, wrap_table=cfg.wrap.table)
    written = simulate_clouds(arm, config, mesh, out=args.out, cameras=args.cameras,
                              deform_mm=args.deform, seed=args.seed, voxel=args.voxel, meta=meta)
    if args.json:
        print_json({"clouds": [{"cloud": str(path), "sidecar": str(side), "n_points": n}
                                for path, side, n in written], "config": config.to_dict(),
                     **meta})
    else:
        for path, side, n in written:
            print(f"wrote {path} ({n} points) and {side}")
    return 0


def _add_classify_captures(subparsers):
    p = subparsers.add_parser(
        "classify-captures", help="classify an object from a folder of captured wraps",
        description="Fit the arm in each capture of FOLDER (one cloud a wrap plane, or "
                    "several views of it, each with the sidecar of docs/clouds.md plus "
                    "'plane', 'contact_arc_length' and, for a model that uses the camera's "
                    "view of the object, 'object_view'), in the order of their file names, and "
                    "classify the wraps so far after each: the category from all of them, "
                    "and the one recognised where the strong-prediction rule first held. "
                    "Example: drake-continuum classify-captures results/model captures/")
    p.add_argument("model", help="trained model folder (train or train-active), required")
    p.add_argument("folder", help="folder of captures (.pcd/.ply with .json sidecars), "
                                  "required")
    add_json(p)
    add_config_options(p, "the settings the model records, its training collection's")
    return p


def _run_classify_captures(args):
    from ..learning.model import load_model
    from ..perception.captures import read_captures, recognise_captures
    model = load_model(args.model)
    cfg = saved_model_config(args, model.info)
    arm = cfg.arm()
    out = recognise_captures(model, read_captures(args.folder, arm), config_planes(cfg, arm),
                             cfg.active)
    if args.json:
        print_json(out)
        return 0
    for step, seen in zip(out["steps"], out["observations"]):
        flag = "" if seen.get("confident", True) else " (fit not confident)"
        print(f"{', '.join(seen['clouds'])}: plane {seen['plane']}{flag} -> {step['category']} "
              f"(p = {step['probabilities'][step['category']]:.2f})"
              + (" strong" if step["strong"] else ""))
    got = out["recognised"]
    print(f"{args.folder}: {out['category']} from {out['n_captures']} captures; "
          + (f"recognised as {got['category']} after {got['n_captures']}" if got
             else "no strong prediction"))
    return 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("fit-cloud", _add_fit_cloud, _run_fit_cloud),
    ("compare-real", _add_compare_real, _run_compare_real),
    ("simulate-cloud", _add_simulate_cloud, _run_simulate_cloud),
    ("classify-captures", _add_classify_captures, _run_classify_captures),
]
