"""`demo`, `wrap`: one wrap of one object.
"""

from __future__ import annotations

from .common import (
    UserError,
    add_config_options,
    add_json,
    add_meshcat,
    add_simplify,
    add_units,
    command_config,
    config_planes,
    print_json,
    scaled_mesh,
    serve_meshcat,
    shortcut,
    sized_mesh,
)

__all__ = ["COMMANDS"]


# ----------------------------------------------------------------- demo
# Curls around the shipped mug's body in the horizontal plane of the arm's base (z = 5 cm):
# section 1 swings out to -y, sections 2 and 3 follow a circle 0.5 mm inside the tube's
# touching radius about the body's axis, 270 deg round (through the handle's hole).
DEMO_CONFIG = {"s": [0.1402, 0.1373, 0.1373], "kappa": [4.408, 19.42, 19.42],
               "phi": [-1.5707963267948966, 1.5707963267948966, 1.5707963267948966]}


def _add_demo(subparsers):
    p = subparsers.add_parser(
        "demo", help="pose the arm around the mug, print its contacts, draw them",
        description="Pose the arm in a hand-chosen configuration that curls around the "
                    "shipped mug and touches it; print the contacts (position, normal from "
                    "the object into the arm, section) and draw them to OUT/demo.png. "
                    "Example: drake-continuum demo --out out/demo --html out/demo.html")
    p.add_argument("--out", default="out/demo", help="output directory (default: out/demo)")
    p.add_argument("--mesh", default=None,
                   help="object mesh in the standard pose; the pose is chosen for the "
                        "shipped mug (default: models/mug.obj)")
    p.add_argument("--html", default=None, metavar="FILE",
                   help="also save a Meshcat page of the arm curling in, e.g. out/demo.html "
                        "(default: none)")
    add_json(p)
    return p


def _contacts_table(contacts) -> str:
    rows = [f"{'#':>2} {'section':>7} {'arc (m)':>8}  {'p (m)':^26}  {'n (object -> arm)':^24}"
            f" {'area (mm^2)':>11}"]
    for i in range(len(contacts)):
        p, n = contacts.p[i], contacts.n[i]
        rows.append(f"{i:>2} {contacts.section[i] + 1:>7d} {contacts.arc_length[i]:>8.4f}  "
                    f"{p[0]:>8.4f} {p[1]:>8.4f} {p[2]:>8.4f}  "
                    f"{n[0]:>7.3f} {n[1]:>7.3f} {n[2]:>7.3f} {1e6 * contacts.area[i]:>11.1f}")
    return "\n".join(rows)


def _run_demo(args):
    from pathlib import Path

    import numpy as np

    from ..kinematics.arm import MODELS_DIR, ArmConfig, load_arm
    from ..viz.meshcat import save_html, show_wrap
    from ..viz.plots import plot_wrap
    from ..wrapping.scene import WrapScene
    arm = load_arm()
    mesh = Path(args.mesh) if args.mesh else MODELS_DIR / "mug.obj"
    config = ArmConfig.from_dict(DEMO_CONFIG)
    scene = WrapScene(arm, mesh)
    scene.set_config(config)
    contacts = scene.contacts()
    out = Path(args.out)
    png = plot_wrap(scene.object_trimesh, arm, config, contacts=contacts, path=out / "demo.png",
                    title=f"{mesh.name}: {len(contacts)} contacts")
    html = None
    if args.html:
        curl = [ArmConfig(config.s, config.kappa * [1.0, a, a], config.phi)
                for a in np.linspace(0.6, 1.0, 25)]
        meshcat, _ = show_wrap(arm, mesh, curl, contacts=contacts)
        html = save_html(meshcat, args.html,
                         title=f"demo: {mesh.name}, {len(contacts)} contacts")
    if args.json:
        print_json({"object": str(mesh), "config": config.to_dict(),
                     "contacts": [{"section": int(contacts.section[i]) + 1,
                                   "arc_length": float(contacts.arc_length[i]),
                                   "p": contacts.p[i], "n": contacts.n[i],
                                   "area_mm2": 1e6 * float(contacts.area[i])}
                                  for i in range(len(contacts))],
                     "png": str(png), "html": None if html is None else str(html)})
        return 0
    print(f"object {mesh}; arm s = {np.round(config.s, 4).tolist()} m, "
          f"kappa = {np.round(config.kappa, 3).tolist()} 1/m, "
          f"phi = {np.round(config.phi, 4).tolist()} rad")
    if len(contacts):
        print(f"{len(contacts)} contacts (sections numbered from 1 at the base):")
        print(_contacts_table(contacts))
    else:
        print("no contacts: the demo pose is chosen for the shipped mug")
    print(f"wrote {png}")
    if html is not None:
        print(f"wrote {html}")
    return 0


# ----------------------------------------------------------------- wrap
def _add_wrap(subparsers):
    p = subparsers.add_parser(
        "wrap", help="wrap one object on one plane (Algorithm 1) and show or save the wrap",
        description="Run the touch-driven wrap (the paper's Algorithm 1) of one object on one "
                    "plane: a default plane by index (--plane) or a plane rotated about world "
                    "x (--rx) or y (--ry). Prints a summary (or --json); --meshcat animates it "
                    "in Drake's Meshcat, --html saves that animation as one page, --png draws "
                    "the final wrap. Example: drake-continuum wrap models/mug.obj --plane 1 "
                    "--png out/wrap.png")
    p.add_argument("object", help="object mesh file, or an object id with --dataset (required)")
    p.add_argument("--dataset", default=None,
                   help="dataset folder (manifest.json) to look OBJECT up in as an id, e.g. "
                        "data/objects (default: OBJECT is a mesh file)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--plane", type=int, default=None,
                       help="index of a default plane (0-9: about x, then about y, every 22.5 "
                            "deg; default: none)")
    which.add_argument("--rx", type=float, default=None,
                       help="plane rotated this many degrees about world x (default: none)")
    which.add_argument("--ry", type=float, default=None,
                       help="plane rotated this many degrees about world y (default: none)")
    p.add_argument("--direction", choices=["cw", "ccw"], default=None,
                   help="wrap direction about the plane normal, with --rx/--ry (default: cw "
                        "about x, ccw about y, as the paper's Fig. 4)")
    p.add_argument("--method", choices=["fast", "reference"], default=None,
                   help="enclosing: fast (distance-bounded) or reference (a contact query "
                        "every step), a shortcut for --set wrap.method=... (default: the "
                        "configuration's, fast)")
    add_meshcat(p, "the wrap")
    p.add_argument("--chords", action="store_true",
                   help="with --meshcat/--html, also draw the wrap's chords (default: off)")
    p.add_argument("--html", default=None, metavar="FILE",
                   help="save the Meshcat animation as a self-contained page, e.g. "
                        "out/wrap.html (default: none)")
    p.add_argument("--png", default=None,
                   help="draw the final wrap to this PNG, e.g. out/wrap.png (default: none)")
    add_json(p)
    add_units(p)
    add_simplify(p)
    add_config_options(p)
    return p


def _wrap_object_mesh(args):
    """(mesh path, name) of the command's object."""
    from pathlib import Path

    from ..objects.dataset import DatasetError, load_manifest
    if args.dataset is None:
        path = Path(args.object)
        if not path.exists():
            raise UserError(f"{path}: no such mesh file (give --dataset DIR to look it up "
                            f"as an object id)")
        return path, path.name
    try:
        entry = load_manifest(args.dataset).by_id(args.object)
    except (DatasetError, KeyError) as e:
        raise UserError(e.args[0] if e.args else str(e)) from None
    return entry.path, entry.id


def _wrap_plane(args, arm, cfg):
    import numpy as np

    from ..wrapping.planes import make_plane
    if args.plane is not None:
        planes = config_planes(cfg, arm)
        if not 0 <= args.plane < len(planes):
            raise UserError(f"--plane must lie in 0..{len(planes) - 1}, got {args.plane}")
        if args.direction is not None:
            raise UserError("--direction goes with --rx or --ry; a default plane has its own")
        return planes[args.plane]
    axis, angle = ("x", args.rx) if args.rx is not None else ("y", args.ry)
    if not np.isfinite(angle):
        raise UserError(f"--r{axis} must be a finite angle in degrees, got {angle}")
    direction = None if args.direction is None else (1 if args.direction == "ccw" else -1)
    return make_plane(arm.base_position, axis, angle, direction=direction)


def _run_wrap(args):
    import numpy as np

    from ..objects.mesh import MeshError, load_mesh
    from ..viz.meshcat import show_wrap, wrap_title
    from ..viz.plots import plot_wrap, wrap_chord_segments
    from ..wrapping.scene import WrapScene
    from ..wrapping.wrap import wrap
    cfg = command_config(args, shortcut("wrap.method", args.method), uses=("arm", "planes", "wrap"))
    arm = cfg.arm()
    mesh, name = _wrap_object_mesh(args)
    plane = _wrap_plane(args, arm, cfg)
    try:
        loaded = load_mesh(mesh)
        if args.units != "m":
            loaded = scaled_mesh(loaded, mesh, args.units)
            mesh = loaded  # WrapScene and the pictures take the scaled trimesh
        else:
            scaled_mesh(loaded.copy(), mesh, args.units)  # only the size check
        sized = sized_mesh(loaded, mesh, args.simplify)
        if sized is not loaded:
            mesh = sized  # WrapScene and the pictures take the simplified trimesh
        scene = WrapScene(arm, mesh)
    except MeshError as e:
        raise UserError(str(e)) from None
    result = wrap(scene, plane, cfg.wrap)
    summary = {"object": name, "plane": plane.to_dict(), "method": cfg.wrap.method,
               "status": result.status, "n_contacts": len(result.contacts),
               "tip_rotation_deg": float(np.degrees(result.tip_rotation)),
               "n_queries": int(result.n_queries), "time_ms": 1000.0 * result.time_s,
               "config": result.final_config.to_dict()}
    if "message" in result.extra:
        summary["message"] = result.extra["message"]
    wrap_arm = result.arm(arm)
    if args.png:
        summary["png"] = str(plot_wrap(
            scene.object_trimesh, wrap_arm, result.final_config, contacts=result.contacts,
            path=args.png,
            title=f"{name} {plane.label}: {result.status}, {len(result.contacts)} contacts"))
    if args.meshcat or args.html:
        chords = wrap_chord_segments(result) if args.chords else None
        meshcat, _ = show_wrap(wrap_arm, mesh, result.configs, contacts=result.contacts,
                               chords=chords, html_path=args.html,
                               title=wrap_title(name, plane.label, result))
        if args.html:
            summary["html"] = str(args.html)
        if args.meshcat:  # without it the server ends with the command: no URL to give
            summary["meshcat_url"] = meshcat.web_url()
    with serve_meshcat(args):  # the URL, then serving: one Ctrl-C-safe block
        if args.json:
            print_json(summary)
        else:
            print(f"{name} {plane.label} ({cfg.wrap.method}): {result.status}, "
                  f"{len(result.contacts)} contacts, tip turned "
                  f"{summary['tip_rotation_deg']:.0f} deg, {result.n_queries} contact queries, "
                  f"{summary['time_ms']:.0f} ms"
                  + (f"; {summary['message']}" if "message" in summary else ""))
            for key in ("png", "html"):
                if key in summary:
                    print(f"wrote {summary[key]}")
            if "meshcat_url" in summary:
                print(f"Meshcat: {summary['meshcat_url']}")
    return 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("demo", _add_demo, _run_demo),
    ("wrap", _add_wrap, _run_wrap),
]
