"""What the commands share: the configuration options, JSON output, loading a collection,
meshes placed on the table, arm configurations given as text.
"""

from __future__ import annotations

import json
import logging
import signal
import sys
from contextlib import contextmanager
from pathlib import Path

from .. import workers
from ..errors import DrakeContinuumError

__all__ = ["UserError", "add_json", "add_config_options", "command_config", "shortcut",
           "print_json", "placement_kinds", "set_down", "load_objects", "add_strict",
           "check_categories", "add_simplify", "sized_mesh", "add_units", "scaled_mesh",
           "add_placed_mesh_options", "placed_scene", "saved_model_config", "config_planes",
           "parse_floats", "read_arm_config", "WRAPPABLE_EXTENT", "old_spelling", "add_bearing",
           "add_meshcat", "serve_meshcat", "add_observe_options", "observe_options",
           "observation_summary", "check_limit_per_category", "check_out_apart"]

log = logging.getLogger("drake_continuum")


class UserError(DrakeContinuumError):
    """An error the user can fix; printed without a traceback."""


def add_config_options(p, default="models/config.yaml"):
    """--config and --set: the experiment configuration of a command that wraps, collects,
    trains or recognises."""
    p.add_argument("--config", default=None, metavar="FILE",
                   help=f"experiment configuration YAML, e.g. my-config.yaml (default: "
                        f"{default})")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one configuration entry, e.g. --set wrap.delta=0.002 "
                        "(repeatable; default: none)")


def add_bearing(p):
    """--bearing: the plane set fixed to the robot or oriented on the object."""
    from ..perception.bearing import BEARINGS
    p.add_argument("--bearing", choices=list(BEARINGS), default=None,
                   help="world: the wrap planes fixed to the robot (the paper's); object: the "
                        "plane set turned about the object onto its horizontal axis as the "
                        "depth camera sees it (a near-round footprint keeps the world "
                        "bearing); a shortcut for --set planes.bearing=... (default: the "
                        "configuration's, object)")


def command_config(args, *shortcuts, uses=None, defaults=()):
    """The command's configuration: --config, then the command's `defaults` and its own
    options given as "key=value" shortcuts (None values skipped), then --set. An option and
    a --set that give one key different values are refused; `uses`: the sections the
    command reads, a --set in another is named in a warning (it changes nothing)."""
    from ..config import load_config, parse_override
    given = [s for s in shortcuts if s is not None]
    options = dict(parse_override(s) for s in given)
    for assignment in args.set:
        key, value = parse_override(assignment)
        if key in options and options[key] != value:
            raise UserError(f"--set {assignment} contradicts the command's own option, which "
                            f"sets {key} to {options[key]!r}; give one of them")
        section = key.split(".")[0]
        if uses is not None and section not in uses:
            print(f"warning: --set {assignment}: `{args.command}` does not use the "
                  f"{section} settings; it changes nothing", file=sys.stderr)
    return load_config(args.config, list(defaults) + given + list(args.set))


def shortcut(key: str, value):
    """"key=value" for an option that sets a configuration entry, None when not given."""
    from ..files import json_text
    if value is None:
        return None
    return f"{key}={json_text(value, indent=None)}"


def old_spelling(p, option: str, dest: str, **kwargs):
    """An option's underscore spelling of earlier versions (--base_pose): still accepted,
    shown nowhere (usage and help give the dashed one)."""
    import argparse
    p.add_argument(option, dest=dest, help=argparse.SUPPRESS, default=argparse.SUPPRESS,
                   **kwargs)


def add_json(p):
    """--json, the same on every command: stdout then holds one JSON document and nothing
    else (logs, warnings and progress bars always go to stderr)."""
    p.add_argument("--json", action="store_true",
                   help="print the result as one JSON document on stdout (default: text)")


def print_json(obj) -> None:
    from ..files import json_text
    sys.stdout.write(json_text(obj) + "\n")


def placement_kinds() -> dict:
    from ..objects.placement_kinds import KINDS
    return KINDS


def check_limit_per_category(args) -> None:
    """Refuse --limit-per-category below 1 by the option's name, before the library names
    its parameter."""
    if args.limit_per_category is not None and args.limit_per_category < 1:
        raise UserError(f"--limit-per-category must be at least 1, got "
                        f"{args.limit_per_category}")


def check_out_apart(args, what: str = "the model") -> None:
    """Refuse an --out that is a wrap collection (its index.json), one the command reads
    (--placed's and --test's too) or inside one, before the work: `what` would be written
    among the wraps."""
    from ..experiments.collection import INDEX_NAME
    from ..files import separate_folders
    for wraps in [args.wraps, *getattr(args, "placed", []), *getattr(args, "test", [])]:
        separate_folders(args.out, wraps, "--out", error=UserError)
    if (Path(args.out) / INDEX_NAME).is_file():
        raise UserError(f"--out {args.out}: holds a wrap collection ({INDEX_NAME}); {what} "
                        f"would be written among its wraps; choose another folder")


def set_down(args, where: str):
    """The Placement of --rest-pose/--turn/--offset, or None when none is given."""
    import math

    from ..objects.placement import Placement
    if args.rest_pose is None and args.turn is None and args.offset is None:
        return None
    offset = (0.0, 0.0) if args.offset is None else tuple(parse_floats(args.offset, 2, "--offset"))
    return Placement(args.rest_pose, math.radians(args.turn or 0.0), offset)


def load_objects(wraps_dir, chords, strict: bool = False):
    """Wrap collection -> (ObjectRecords, skipped), chords as ChordParams `chords`; the
    objects left out are named on stderr, or with `strict` refused."""
    import warnings

    from ..learning.records import WrapDataWarning, load_collection
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", WrapDataWarning)
        objects, skipped = load_collection(wraps_dir, chords)
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    if skipped and strict:
        raise UserError(f"{wraps_dir}: {len(skipped)} object(s) cannot be used (--strict): "
                        + "; ".join(f"{s['object_id']}: {s['reason']}" for s in skipped))
    for s in skipped:
        print(f"warning: skipped object {s['object_id']}: {s['reason']}", file=sys.stderr)
    return objects, skipped


def add_strict(p):
    p.add_argument("--strict", action="store_true",
                   help="fail if any object of the collection is missing, damaged or failed "
                        "in collection (default: leave it out, named on stderr and in the "
                        "outputs)")


def check_categories(objects, minimum: int, why: str) -> None:
    """At least 2 categories, and every category with at least `minimum` objects (`why`)."""
    from collections import Counter
    counts = Counter(o.category for o in objects)
    few = {c: n for c, n in counts.items() if n < minimum}
    if len(counts) < 2 or few:
        raise UserError(f"every category needs at least {minimum} objects ({why}) and there "
                        f"must be at least 2 categories; "
                        + (f"too few in {few}; " if few else "")
                        + f"the collection holds {dict(counts)}")


def add_simplify(p):
    p.add_argument("--simplify", type=float, default=None, metavar="MM",
                   help="decimate the mesh (Open3D quadric decimation) to the fewest "
                        "triangles that stay within MM millimetres of its surface, e.g. 0.5; "
                        "worth it above 100,000 triangles, where a wrap takes tens of seconds "
                        "(default: the mesh as given)")


def sized_mesh(mesh, name, simplify_mm):
    """The mesh to wrap: as given, with a warning if it is large (objects.mesh.size_warning),
    or with --simplify decimated to within that many millimetres, saying what it did."""
    import math

    from ..objects.mesh import simplify_mesh, size_warning
    if simplify_mm is None:
        warning = size_warning(mesh, name)
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
        return mesh
    if not (math.isfinite(simplify_mm) and simplify_mm > 0):
        raise UserError(f"--simplify must be a positive number of millimetres, got "
                        f"{simplify_mm}")
    low, deviation = simplify_mesh(mesh, simplify_mm / 1000.0)
    print(f"simplified {name}: {len(mesh.faces):,} -> {len(low.faces):,} triangles, at most "
          f"{1000 * deviation:.2f} mm from the original surface (--simplify {simplify_mm:g})",
          file=sys.stderr)
    return low


def add_units(p):
    p.add_argument("--units", choices=["m", "cm", "mm"], default="m",
                   help="units of the mesh file's coordinates; a mesh far too large or too "
                        "small for the arm is refused with the units it seems to be in "
                        "(default: m)")


# Largest extent of a mesh the arm can wrap, m: its sections reach about 0.5 m; an object
# beyond these bounds is a mesh in other units (a mug in millimetres is 110 m across).
WRAPPABLE_EXTENT = (0.005, 1.0)


def scaled_mesh(mesh, path, units: str):
    """The mesh in metres (--units), refused naming the file and the units that fit when its
    size is no object the arm could wrap."""
    from ..objects.importer import UNITS, guess_units
    mesh.apply_scale(UNITS[units])
    extent = float(max(mesh.extents))
    low, high = WRAPPABLE_EXTENT
    if low <= extent <= high:
        return mesh
    likely = guess_units(extent / UNITS[units], category="")
    names = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
    hint = (f"is it in {names[likely]}? try --units {likely}" if likely != units
            else "check its units (--units m, cm or mm)")
    raise UserError(f"{path}: {extent:.4g} m across with --units {units}, "
                    f"{'larger' if extent > high else 'smaller'} than any object the arm can "
                    f"wrap ({1000 * low:g} mm to {high:g} m); {hint}")


def add_placed_mesh_options(p):
    """The options of a mesh where it stands (classify, recognize)."""
    add_units(p)
    p.add_argument("--rest-pose", type=int, default=None,
                   help="set the object down on this stable pose (0: the most probable; "
                        "trimesh's stable poses) at the mark (default: where it stands)")
    p.add_argument("--turn", type=float, default=None,
                   help="set it down turned this many degrees about the vertical "
                        "(default: where it stands)")
    p.add_argument("--offset", default=None,
                   help="set it down this far from the mark, x,y in m, e.g. 0.05,-0.02 "
                        "(default: where it stands)")
    p.add_argument("--position", default=None,
                   help="where you think the object is, x,y in m (within about 2 cm), e.g. "
                        "0.05,-0.02: the arm's planes are centred there (default: estimated "
                        "from the simulated depth camera's cloud)")


def add_observe_options(p):
    """How classify and recognize know the arm's shape: exactly, or through the camera."""
    p.add_argument("--observe", choices=["exact", "camera"], default="exact",
                   help="how each wrap's configuration is known: exact (the simulator's) or "
                        "camera (fitted to the simulated depth camera's cloud of the arm; "
                        "the fit's flags are printed with the result) (default: exact)")
    p.add_argument("--views", type=int, default=1,
                   help="with --observe camera, cameras spread round the object, fitted "
                        "together (default: 1)")
    p.add_argument("--transparent", action="store_true",
                   help="the object is transparent: the depth camera sees the arm whole and "
                        "nothing of the object, so the arm is lined up on --position and "
                        "the model must not use the camera's view of the object (train it "
                        "with --touch-only) (default: off)")
    p.add_argument("--camera-seed", type=int, default=0,
                   help="seed of the depth camera's noise, with --observe camera "
                        "(default: 0)")


def observe_options(args, model) -> dict | None:
    """observe_wrap's options from --observe/--views/--transparent, None for exact; a
    UserError for a model that needs the transparent object visible."""
    if args.views < 1:
        raise UserError(f"--views must be at least 1, got {args.views}")
    blocks = getattr(model, "needs_object_visible", ())
    if args.transparent and blocks:
        raise UserError(f"{args.model}: its {', '.join(blocks)} block needs the object "
                        f"visible, which a transparent one is not; train a model with "
                        f"--touch-only")
    if args.observe == "exact":
        return None
    return {"views": args.views, "transparent": args.transparent, "seed": args.camera_seed}


def observation_summary(observations) -> str:
    """One line of the fits' flags: wraps fitted, flagged, not seen, median CPU time."""
    import numpy as np
    fitted = [o for o in observations if "error" not in o]
    flagged = [o["plane"] for o in fitted if not o.get("confident", True)]
    missed = [o["plane"] for o in observations if "error" in o
              and not o["error"].startswith("wrap not usable")]
    cpu = np.median([o["cpu_s"] for o in fitted]) if fitted else 0.0
    return (f"{len(fitted)} wraps fitted ({cpu:.2f} s CPU each, median)"
            + (f", not confident on planes {flagged}" if flagged else "")
            + (f", arm not found on planes {missed}" if missed else ""))


def placed_scene(args, arm, bearing: str = "world"):
    """(WrapScene, world mesh, position info) of a mesh where it stands (or set down by
    --rest-pose/--turn/--offset), seen from `arm` lined up on --position or the depth
    camera's estimate, and with bearing "object" the plane set turned onto the object's
    axis in the camera's cloud (perception.bearing); never on the mesh's own geometry. The
    position info holds the camera's view of the object ("view", perception.locate.
    view_extent; None when the camera found nothing and --position and --bearing world made
    it unnecessary for lining up)."""
    import numpy as np

    from ..objects.mesh import MeshError, load_mesh, standard_pose
    from ..objects.placement import PlacementError, arm_frame, check_reachable, place
    from ..perception.bearing import PlaneBearing, bearing_turn, points_bearing
    from ..perception.locate import (
        LocateError,
        camera_points,
        footprint_centre,
        points_estimate,
        view_extent,
    )
    from ..wrapping.scene import WrapScene
    try:
        mesh = load_mesh(args.mesh)
    except MeshError as e:
        raise UserError(str(e)) from None
    mesh = scaled_mesh(mesh, args.mesh, args.units)
    where = f"{args.mesh}"
    mesh = sized_mesh(mesh, where, args.simplify)
    given = set_down(args, "")
    try:
        if given is not None:
            mesh = place(mesh, given, where=f"{where} set down")
        table = float(standard_pose().get("table_height", 0.0))
        low = float(mesh.vertices[:, 2].min())
        if abs(low - table) > 0.002:
            raise UserError(f"{where}: its lowest point is at z = {low:.4f} m, not on the table "
                            f"(z = {table} m); move it there, or set it down with --turn 0")
        seen = None  # the object's points in the depth camera's cloud, rendered once
        try:
            if getattr(args, "transparent", False):
                raise LocateError("transparent: the depth camera does not see it")
            seen = camera_points(mesh, arm)
        except LocateError as e:
            if args.position is None or bearing != PlaneBearing.WORLD:
                raise UserError(f"{where}: {e}; give --position X,Y"
                                + (" and --set planes.bearing=world"
                                   if bearing != PlaneBearing.WORLD else "")) from None
        if args.position is not None:
            centre = np.array(parse_floats(args.position, 2, "--position"))
            if not np.all(np.isfinite(centre)):
                raise UserError(f"--position {args.position}: not two finite numbers")
            source = "--position"
        else:
            centre = points_estimate(seen).xy
            source = "depth camera"
        turn = (bearing_turn(bearing, None, arm) if bearing == PlaneBearing.WORLD
                else points_bearing(seen))
        local = arm_frame(mesh, centre, turn.turn)
        check_reachable(local, arm, f"{where} centred on {np.round(centre, 4).tolist()}")
    except PlacementError as e:
        raise UserError(str(e)) from None
    error = float(np.linalg.norm(centre - footprint_centre(mesh)))
    log.info("%s: arm centred on (%.4f, %.4f) m from the %s (%.1f mm from the footprint "
             "centre)", where, centre[0], centre[1], source, 1000 * error)
    position = {"centre": np.asarray(centre, float).round(5).tolist(), "from": source,
                "error_mm": round(1000 * error, 2), "bearing": turn.to_dict(),
                "view": None if seen is None else view_extent(seen).round(6).tolist()}
    return WrapScene(arm, local), mesh, position


def saved_model_config(args, info):
    """The configuration a model's object is wrapped with: the one it records (its training
    collection's wraps), then --config/--set; warnings on stderr."""
    from ..config import model_config
    cfg, warnings = model_config(info, args.config, args.set)
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    return cfg


def config_planes(cfg, arm):
    from ..wrapping.planes import enumerate_planes
    return enumerate_planes(arm.base_position, cfg.alpha_deg, cfg.both_directions)


def parse_floats(text, n, name):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != n:
        raise UserError(f"{name} needs {n} comma-separated numbers, got {text!r}")
    return values


def read_arm_config(text, name):
    """An ArmConfig from a JSON file or text (bare, or under "config" as in a sidecar)."""
    from ..kinematics.arm import ArmConfig
    try:
        if not text.lstrip().startswith("{"):
            text = Path(text).read_text()
        d = json.loads(text)
        return ArmConfig.from_dict(d.get("config", d))
    except OSError as e:
        raise UserError(f"{name} {text}: cannot be read ({e.strerror})") from None
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise UserError(f"{name}: not an arm configuration ({e})") from None


def add_meshcat(p, what: str):
    """--meshcat and --no-wait of a command that can show its wrap."""
    p.add_argument("--meshcat", action="store_true",
                   help=f"animate {what} in Meshcat, print its URL and serve it until you "
                        "press Enter or Ctrl-C (default: off)")
    p.add_argument("--no-wait", dest="no_wait", action="store_true",
                   help="with --meshcat, exit at once instead of serving until Enter "
                        "(default: wait)")


@contextmanager
def serve_meshcat(args):
    """Print the command's output inside this block, then keep the Meshcat server (it ends
    with the process) up until Enter or Ctrl-C.

    A reader acts on the URL as soon as it is printed (at once when stdout is unbuffered,
    PYTHONUNBUFFERED=1, as on CI runners), and may press Ctrl-C before the serving begins:
    with --meshcat, a Ctrl-C from the first line printed on ends the command quietly (a test
    caught one that landed between the URL and the wait)."""
    if not args.meshcat or args.no_wait:
        yield
        sys.stdout.flush()
        return
    try:
        yield
        sys.stdout.flush()
        print("Meshcat is serving; press Enter (or Ctrl-C) to quit.", file=sys.stderr)
        if not sys.stdin.readline():  # no terminal to press Enter in: serve until Ctrl-C
            signal.pause()
    except KeyboardInterrupt:
        workers.sigint_handled()
