"""The example scripts in sim/ run end to end as a user would start them: stand_and_touch.py
and collect_dataset.py (slow) in a subprocess, the others in the test's process as
`python sim/NAME` runs them (runpy, as __main__, with their arguments and folder), where a
second interpreter would only import the package again."""

import runpy
import subprocess
import sys
from pathlib import Path

import pytest

from synthetic_wraps import separable_objects, write_collection

ROOT = Path(__file__).resolve().parents[1]


def run_script(name, *args, timeout=600, cwd=ROOT):
    done = subprocess.run([sys.executable, str(ROOT / "sim" / name), *map(str, args)],
                          cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def run_script_here(name, *args, cwd, monkeypatch, capsys):
    """sim/NAME run as __main__ in this process from folder `cwd`: what it printed."""
    script = ROOT / "sim" / name
    monkeypatch.chdir(cwd)
    monkeypatch.setattr(sys, "argv", [str(script), *map(str, args)])
    capsys.readouterr()
    runpy.run_path(str(script), run_name="__main__")
    return capsys.readouterr().out


def test_wrap_in_meshcat_saves_the_animation(tmp_path, monkeypatch, capsys):
    page = tmp_path / "wrap.html"
    out = run_script_here("wrap_in_meshcat.py", "--plane", 1, "--html", page, cwd=ROOT,
                          monkeypatch=monkeypatch, capsys=capsys)
    assert out.splitlines()[0].startswith("complete:")  # in plane 0 the handle stops it (at_limits)
    assert page.stat().st_size > 10_000 and "meshcat" in page.read_text().lower()


def test_simulate_wrap_records_the_page_and_writes_the_cloud(tmp_path, monkeypatch, capsys):
    """The station script of at most 30 lines: a complete wrap, the page with its
    recording, and a cloud in which the arm's orange is seen."""
    from drake_continuum.perception.cloud import load_cloud

    assert len((ROOT / "sim" / "simulate_wrap.py").read_text().splitlines()) <= 30
    out = run_script_here("simulate_wrap.py", cwd=tmp_path, monkeypatch=monkeypatch,
                          capsys=capsys)
    assert out.startswith("complete: 3 contacts"), out
    page = (tmp_path / "wrap.html").read_text()
    assert len(page) > 10_000 and "meshcat" in page.lower() and "animation" in page
    cloud = load_cloud(tmp_path / "cloud.ply")
    points, colours = cloud.points, cloud.colours
    assert len(points) > 50_000
    orange = (colours[:, 0] > 0.5) & (colours[:, 0] > 1.6 * colours[:, 2])
    assert orange.sum() > 500


@pytest.mark.slow
def test_stand_and_touch_composes_the_station_with_parts_of_its_own():
    """A stand lowers the base while a trajectory curls the arm: no touch at first, then the
    mug's rim under the arm's middle section."""
    lines = run_script("stand_and_touch.py").strip().splitlines()
    assert lines[0].startswith("t = 0.00 s: 0 touches")
    assert "sections [1]" in lines[-1] and not lines[-1].split(": ")[1].startswith("0 ")


def test_recognize_object_names_a_trained_category(tmp_path, monkeypatch, capsys):
    write_collection(tmp_path / "wraps", separable_objects(4, 4))
    out = run_script_here("recognize_object.py", tmp_path / "wraps", cwd=ROOT,
                          monkeypatch=monkeypatch, capsys=capsys)
    assert out.startswith("iteration 1:")
    last = out.strip().splitlines()[-1]
    assert last.split()[2] in ("circle", "square"), last


@pytest.mark.slow
def test_collect_dataset_evaluates_a_small_collection(tmp_path):
    out = run_script("collect_dataset.py", "--out", tmp_path / "sim", timeout=3600)
    accuracy = float(out.split("accuracy over 10 splits: ")[1].split("%")[0])
    assert 50.0 < accuracy <= 100.0  # ten categories: chance is 10 %
    assert len(list((tmp_path / "sim" / "wraps").glob("*.npz"))) == 40
