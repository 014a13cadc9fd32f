"""The command line's conventions (issue 17): --version, `python -m drake_continuum`,
-v/-q on either side of the command, --json on every command (stdout one JSON document, text
by default), dashed option spellings only, --html a path on demo and wrap, no Meshcat URL
for a server that dies with the command, --units and meshes in the wrong units, the Dask
extra."""

import argparse
import json
import logging
import re
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh

from drake_continuum import cli
from drake_continuum.kinematics.arm import MODELS_DIR
from synthetic_wraps import separable_objects, write_collection

ROOT = Path(__file__).resolve().parents[2]
MUG = MODELS_DIR / "mug.obj"


def _run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _command(*argv, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "drake_continuum", *map(str, argv)],
                          cwd=cwd, capture_output=True, text=True, timeout=600)


def _parsers():
    """(name, parser) of every command and of `objects`' actions."""
    parser = cli.build_parser()
    found = []

    def walk(p, name):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            found.append((name, p))
        for a in subs:
            for child, sp in a.choices.items():
                walk(sp, f"{name} {child}".strip())
    walk(parser, "")
    return parser, found


@pytest.fixture(scope="module")
def wraps(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wraps")
    write_collection(folder, separable_objects(4, 3))
    return folder


# ------------------------------------------------------------------ version, -m, -v/-q

def test_version_and_python_m_drake_continuum():
    version = re.search(r'^version = "(.+)"$', (ROOT / "pyproject.toml").read_text(),
                        re.M).group(1)
    done = _command("--version")
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"drake-continuum {version}\n"
    done = _command("--help")
    assert done.returncode == 0 and done.stdout.startswith("usage: drake-continuum")


def test_verbose_and_quiet_go_before_or_after_the_command():
    parser = cli.build_parser()
    for argv in (["-v", "evaluate", "W"], ["evaluate", "W", "-v"], ["evaluate", "-v", "W"]):
        args = parser.parse_args(argv)
        assert args.verbose and not args.quiet, argv
    for argv in (["-q", "evaluate", "W"], ["evaluate", "W", "--quiet"]):
        args = parser.parse_args(argv)
        assert args.quiet and not args.verbose, argv
    args = parser.parse_args(["evaluate", "W"])
    assert not args.quiet and not args.verbose
    with pytest.raises(SystemExit):
        cli.main(["-v", "evaluate", "W", "-q"])


def test_quiet_silences_the_logs_on_either_side(wraps, tmp_path, capsys, caplog):
    """`evaluate` logs its accuracy at INFO on stderr (as a user runs it); -q leaves warnings
    only (in this process: no record of the package's under WARNING), and stdout is the same.
    (-q after the command, where it is easier to lose: that either place sets the same flag
    is test_verbose_and_quiet_go_before_or_after_the_command's.)"""
    argv = ["evaluate", wraps, "--splits", 2, "--out", tmp_path / "e"]
    plain = _command(*argv)
    assert plain.returncode == 0, plain.stderr
    assert "INFO" in plain.stderr
    caplog.set_level(logging.DEBUG, logger="drake_continuum")
    rc, out, err = _run(capsys, *argv, "-q")
    assert rc == 0, err
    assert not [r for r in caplog.records
                if r.name.startswith("drake_continuum") and r.levelno < logging.WARNING]
    assert "INFO" not in err
    assert out == plain.stdout


# ------------------------------------------------------------------ uniform options

def test_every_command_takes_json_and_shows_only_dashed_spellings():
    parser, parsers = _parsers()
    names = {n for n, _ in parsers}
    assert {"wrap", "demo", "collect", "train", "objects generate", "objects show",
            "simulate-cloud", "reproduce"} <= names
    assert len(parsers) == len(cli.COMMANDS) - 1 + 4  # objects has four actions
    for name, p in parsers:
        text = p.format_help()
        assert "--json" in text, name
        assert "-q, --quiet" in text and "-v, --verbose" in text, name
        underscored = re.findall(r"--[a-z0-9]+_[a-z0-9_]+", text)
        assert not underscored, f"{name}: {underscored}"
    # The old spellings are still understood.
    args = parser.parse_args(["fit-cloud", "c.pcd", "--base_pose", "0,0,0,0,0,0", "--no_colour"])
    assert args.base_pose == "0,0,0,0,0,0" and args.no_colour
    assert parser.parse_args(["fit-cloud", "c.pcd"]).prior_sigma == "0.01,1.0,0.2"
    assert parser.parse_args(["simulate-cloud", "m.obj", "--arm_config", "{}"]).arm_config == "{}"


def test_train_prints_text_and_with_json_one_document(wraps, tmp_path, capsys):
    """train and train-active print text, and with --json the same facts as one document."""
    rc, out, err = _run(capsys, "train", wraps, "--out", tmp_path / "m")
    assert rc == 0, err
    assert out == f"trained on 8 objects of 2 categories (circle, square); wrote {tmp_path / 'm'}\n"
    rc, out, _ = _run(capsys, "train", wraps, "--out", tmp_path / "m", "--json")
    summary = json.loads(out)
    assert summary["classes"] == ["circle", "square"] and summary["skipped"] == []
    rc, out, _ = _run(capsys, "train-active", wraps, "--out", tmp_path / "a")
    assert rc == 0 and out.startswith("trained on 8 objects of 2 categories;")
    rc, out, _ = _run(capsys, "train-active", wraps, "--out", tmp_path / "a", "--json")
    assert json.loads(out)["n_planes"] == 3


def test_objects_actions_print_text_or_json(tmp_path, capsys):
    from drake_continuum.objects.dataset import generate_dataset
    src = tmp_path / "objects"
    generate_dataset(src, counts={"cup": 1, "apple": 1}, workers=1, progress=False)
    rc, out, err = _run(capsys, "objects", "place", src, "--out", tmp_path / "p",
                        "--placements", "turned=1", "--seed", 3)
    assert rc == 0, err
    assert out == f"wrote {tmp_path / 'p' / 'manifest.json'}: 2 objects (apple 1, cup 1)\n"
    rc, out, err = _run(capsys, "objects", "show", src, "--png", tmp_path / "g.png", "--json")
    assert rc == 0, err
    assert json.loads(out) == {"png": str(tmp_path / "g.png"), "n_objects": 2}


def test_demo_html_is_a_path_and_json_lists_the_contacts(tmp_path, capsys):
    page = tmp_path / "pages" / "curl.html"
    rc, out, err = _run(capsys, "demo", "--out", tmp_path / "d", "--html", page, "--json")
    assert rc == 0, err
    summary = json.loads(out)  # the whole of stdout: no "Meshcat: http..." line before it
    assert summary["html"] == str(page) and page.stat().st_size > 10_000
    assert len(summary["contacts"]) >= 2
    assert {c["section"] for c in summary["contacts"]} <= {1, 2, 3}
    assert "Meshcat" not in out


# ------------------------------------------------------------------ wrap: Meshcat, units

def test_wrap_html_gives_no_meshcat_url_unless_meshcat(tmp_path, capsys):
    page = tmp_path / "w.html"
    argv = ["wrap", MUG, "--plane", 0, "--set", "wrap.theta_deg=90", "--html", page]
    rc, out, err = _run(capsys, *argv)
    assert rc == 0, err
    assert "http" not in out and "Meshcat" not in out
    assert "http" not in err
    assert out.splitlines()[-1] == f"wrote {page}"
    rc, out, err = _run(capsys, *argv, "--json")
    assert "meshcat_url" not in json.loads(out)
    rc, out, err = _run(capsys, *argv, "--json", "--meshcat", "--no-wait")
    assert json.loads(out)["meshcat_url"].startswith("http://")
    # As a user runs it, Drake's own log line ("Meshcat listening ... at http://...") too.
    done = _command(*argv)
    assert done.returncode == 0, done.stderr
    assert "http" not in done.stdout + done.stderr


@pytest.mark.parametrize("when", ["after the page loads", "as the URL appears"])
def test_wrap_meshcat_serves_until_the_user_ends_it(tmp_path, when):
    """With --meshcat the page stays served (also with no terminal on stdin) until Ctrl-C,
    and a Ctrl-C as soon as the URL shows (stdout unbuffered, as on CI runners: the URL is
    out before the serving starts) ends it as quietly (seen under load: exit 130)."""
    import os
    import signal
    import urllib.request
    proc = subprocess.Popen([sys.executable, "-m", "drake_continuum", "wrap", str(MUG),
                             "--plane", "0", "--set", "wrap.theta_deg=90", "--meshcat"],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                            start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        lines = []
        for line in proc.stdout:  # the summary, then the URL
            lines.append(line)
            if line.startswith("Meshcat: "):
                break
        url = lines[-1].split(": ", 1)[1].strip()
        assert url.startswith("http://"), lines
        if when == "after the page loads":
            with urllib.request.urlopen(url, timeout=60) as page:  # still serving
                assert page.status == 200 and b"meshcat" in page.read().lower()
            assert proc.poll() is None
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err
    assert "Traceback" not in err


def _scaled_mug(tmp_path, factor, name):
    mesh = trimesh.load(MUG, force="mesh")
    mesh.apply_scale(factor)
    path = tmp_path / name
    mesh.export(path)
    return path


@pytest.mark.parametrize("factor,units", [(1000.0, "mm"), (100.0, "cm")])
def test_a_mesh_in_other_units_is_refused_naming_the_units(tmp_path, capsys, factor, units):
    """Seen: "the arm base lies inside the object" for the mug in millimetres."""
    path = _scaled_mug(tmp_path, factor, f"mug_{units}.obj")
    rc, out, err = _run(capsys, "wrap", path, "--plane", 0)
    assert rc == 1 and out == ""
    line, = err.strip().splitlines()
    assert line.startswith(f"drake-continuum wrap: error: {path}: ")
    assert line.endswith(f"try --units {units}")


def test_wrap_with_units_equals_the_wrap_in_metres(tmp_path, capsys):
    path = _scaled_mug(tmp_path, 1000.0, "mug_mm.obj")
    common = ["--plane", 1, "--set", "wrap.theta_deg=90", "--json"]
    rc, out, err = _run(capsys, "wrap", MUG, *common)
    metres = json.loads(out)
    rc, out, err = _run(capsys, "wrap", path, "--units", "mm", *common)
    assert rc == 0, err
    mm = json.loads(out)
    assert mm["status"] == metres["status"] and mm["n_contacts"] == metres["n_contacts"]
    assert mm["tip_rotation_deg"] == pytest.approx(metres["tip_rotation_deg"], abs=0.5)


def test_classify_and_recognize_refuse_a_mesh_in_millimetres(wraps, tmp_path, capsys):
    path = _scaled_mug(tmp_path, 1000.0, "mug_mm.obj")
    assert cli.main(["train-active", str(wraps), "--out", str(tmp_path / "m")]) == 0
    capsys.readouterr()
    for command in ("classify", "recognize"):
        rc, out, err = _run(capsys, command, tmp_path / "m", path)
        assert rc == 1, err
        assert f"{path}: " in err and err.strip().endswith("try --units mm"), err


# ------------------------------------------------------------------ the Dask extra

def test_scheduler_without_dask_says_which_extra(tmp_path, capsys, monkeypatch):
    from drake_continuum.objects.dataset import generate_dataset
    generate_dataset(tmp_path / "objects", counts={"cup": 1}, workers=1, progress=False)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails as uninstalled
    monkeypatch.setitem(sys.modules, "distributed", None)
    for argv in (["collect", tmp_path / "objects", "--out", tmp_path / "w",
                  "--scheduler", "tcp://127.0.0.1:1"],
                 ["reproduce", "--quick", "--out", tmp_path / "r",
                  "--scheduler", "tcp://127.0.0.1:1"]):
        rc, out, err = _run(capsys, *argv)
        assert rc == 1
        line, = err.strip().splitlines()
        assert "--scheduler needs Dask's distributed scheduler" in line
        assert "pip install 'drake-continuum[cluster]'" in line
    assert not (tmp_path / "r").exists()  # refused before anything was written


def test_a_limit_per_category_below_one_is_refused_by_the_option(tmp_path, capsys):
    """collect and objects place name --limit-per-category, the option the user typed, not
    the library's parameter, and write nothing."""
    from drake_continuum.objects.dataset import generate_dataset
    generate_dataset(tmp_path / "objects", counts={"cup": 1}, workers=1, progress=False)
    for argv in (["collect", tmp_path / "objects", "--out", tmp_path / "w"],
                 ["objects", "place", tmp_path / "objects", "--out", tmp_path / "p"]):
        rc, out, err = _run(capsys, *argv, "--limit-per-category", 0)
        assert rc == 1
        line, = err.strip().splitlines()
        assert line.endswith("--limit-per-category must be at least 1, got 0"), line
        assert "limit_per_category" not in line
    assert not (tmp_path / "w").exists() and not (tmp_path / "p").exists()


def test_a_model_is_not_written_into_a_wrap_collection(wraps, tmp_path, capsys):
    """train, train-active, evaluate and evaluate-active refuse an --out that is the
    collection they read, a folder in it, or another wrap collection, naming the folder,
    and write nothing there."""
    other = tmp_path / "other"
    write_collection(other, separable_objects(2, 3))
    before = {p: sorted(p.iterdir()) for p in (wraps, other)}
    for command in ("train", "train-active", "evaluate", "evaluate-active"):
        for out, says in ((wraps, f"--out {wraps}: is the input folder {wraps}"),
                          (wraps / "model", f"--out {wraps / 'model'}: is the input folder"),
                          (other, f"--out {other}: holds a wrap collection (index.json)")):
            rc, _, err = _run(capsys, command, wraps, "--out", out)
            assert rc == 1
            line, = err.strip().splitlines()
            assert says in line, line
    assert {p: sorted(p.iterdir()) for p in (wraps, other)} == before


def test_frame_choices_are_the_chord_frames():
    """--frame is spelled out in the CLI (which loads no numpy); it must list every frame
    features.chords knows."""
    import argparse

    from drake_continuum.cli import build_parser
    from drake_continuum.features.chords import FRAMES

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    found = 0
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if "--frame" in action.option_strings:
                assert tuple(action.choices) == FRAMES, name
                found += 1
    assert found >= 3


def test_class_prior_choices_are_train_actives():
    """train-active spells out --class-prior's choices (the CLI loads no numpy); they must be
    active.training's CLASS_PRIORS, its default train_active's."""
    import argparse
    import inspect

    from drake_continuum.active.training import CLASS_PRIORS, train_active
    from drake_continuum.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    action, = (a for a in sub.choices["train-active"]._actions
               if "--class-prior" in a.option_strings)
    assert tuple(action.choices) == CLASS_PRIORS
    assert action.default == inspect.signature(train_active).parameters["class_prior"].default


def test_quick_reproduce_defaults_to_the_quick_placements(tmp_path, monkeypatch, capsys):
    """`reproduce --quick` alone places the copies its help names; --placements and the
    full run keep theirs."""
    from drake_continuum.experiments import reproduce as module
    seen = []

    def fake(settings):
        seen.append(settings)
        settings.out.mkdir(parents=True, exist_ok=True)
        (settings.out / "summary.json").write_text("{}")
        return settings.out / "report.md"
    monkeypatch.setattr(module, "reproduce", fake)
    for argv in (["--quick"], [], ["--quick", "--placements", "nudged=1"]):
        assert cli.main(["reproduce", "--out", str(tmp_path / "r"), *argv]) == 0
    assert [s.placements for s in seen] == [module.QUICK_PLACEMENTS, module.PLACEMENTS,
                                            "nudged=1"]
    assert module.QUICK_PLACEMENTS == "side=1,turned=1"
    capsys.readouterr()


def test_a_negative_list_of_numbers_is_an_options_value():
    """`--offset -0.04,0.02` (as a user types it) parses as `--offset=-0.04,0.02`, where
    argparse alone refuses the line; a single negative number and `--set` keep argparse's
    reading."""
    line = ["classify", "M", "mesh.obj", "--offset", "-0.04,0.02", "--turn", "-30",
            "--position", "-1e-2,-3.5", "--json", "--set", "wrap.delta=0.002"]
    args = cli.build_parser().parse_args(cli._attached_lists(line))
    assert (args.offset, args.turn, args.position, args.json) == ("-0.04,0.02", -30.0,
                                                                "-1e-2,-3.5", True)
    with pytest.raises(SystemExit):  # what argparse alone does with the same line
        cli.build_parser().parse_args(line)
    assert cli._attached_lists(["--json", "-0.5"]) == ["--json", "-0.5"]  # one number
