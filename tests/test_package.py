"""The package as a user meets it: the README's Python example, the public API at the root
(lazy), every module's __all__, the wheel (models/ inside it), the code style (ruff)."""

import ast
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "drake_continuum"


def _readme_python_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("## From Python", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_readme_python_example_runs_and_uses_its_setting(capsys):
    scope = {}
    exec(compile(_readme_python_example(), "README.md", "exec"), scope)
    result = scope["result"]
    assert capsys.readouterr().out.startswith(f"{result.status}: {len(result.contacts)} contacts")
    # The override took effect: the wrap stops once the tip has turned 180 deg, not 270.
    assert result.status == "complete"
    assert np.radians(180) <= result.tip_rotation < np.radians(270)
    assert scope["config"].wrap.theta == pytest.approx(np.pi)


def test_public_api_resolves_and_importing_the_package_loads_no_drake():
    import drake_continuum
    for name in drake_continuum.__all__:
        assert getattr(drake_continuum, name) is not None, name
    # The names shared with a module are the functions, also after the modules are imported.
    import drake_continuum.learning.pipeline  # noqa: F401
    import drake_continuum.wrapping.wrap  # noqa: F401
    from drake_continuum import classify, wrap
    assert callable(wrap) and callable(classify)
    code = ("import sys, drake_continuum; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('pydrake', 'open3d', 'sklearn', 'trimesh', 'matplotlib')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"


def test_every_module_declares_all_and_its_names_exist():
    import importlib
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "__main__.py" or (path.name == "__init__.py" and path.parent != PACKAGE
                                          and path.parent.name != "cli"):
            continue  # a script entry; the subpackages' docstrings (cli/__init__ is a module)
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        module = module.removesuffix(".__init__")
        tree = ast.parse(path.read_text())
        declared = [n for n in tree.body if isinstance(n, ast.Assign)
                    and any(getattr(t, "id", None) == "__all__" for t in n.targets)]
        assert declared, f"{path}: no __all__"
        mod = importlib.import_module(module)
        missing = [n for n in mod.__all__ if not hasattr(mod, n)]
        assert not missing, f"{module}.__all__ names {missing}, which it does not define"


def test_ruff_is_clean():
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent))
    assert ruff, "ruff is not installed: make setup installs the test extra"
    out = subprocess.run([ruff, "check", "--no-cache", "."], cwd=ROOT, capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def _share_compiled_kernels(checkout, unpacked):
    """Give each unpacked module with compiled kernels (compiled.py, proximity.py, ...) the
    checkout's numba cache (numba keys it by the source's size and modification time), so
    that each command run from the wheel does not spend seconds compiling the same kernels;
    a stale cache would only be compiled again."""
    (unpacked / "__pycache__").mkdir(exist_ok=True)
    for source in sorted(checkout.glob("*.py")):
        kernels = sorted((checkout / "__pycache__").glob(f"{source.stem}.*.nb[ic]"))
        if not kernels or (unpacked / source.name).read_bytes() != source.read_bytes():
            continue
        stat = source.stat()
        os.utime(unpacked / source.name, ns=(stat.st_atime_ns, stat.st_mtime_ns))
        for f in kernels:
            shutil.copy2(f, unpacked / "__pycache__" / f.name)


@pytest.fixture(scope="module")
def wheel_site(tmp_path_factory):
    """The wheel built from a copy of the sources and unpacked away from the checkout (as
    `pip install --no-deps --target` would): (wheel, its folder, a working folder there)."""
    tmp_path = tmp_path_factory.mktemp("wheel")
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    for name in ("drake_continuum", "models", "real/data"):
        shutil.copytree(ROOT / name, src / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist),
                    str(src)], check=True, capture_output=True)
    (wheel,) = dist.glob("drake_continuum-*.whl")
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    _share_compiled_kernels(PACKAGE / "kinematics", site / "drake_continuum" / "kinematics")
    run = tmp_path / "elsewhere"
    run.mkdir()
    return wheel, site, run


def test_wheel_ships_the_models_and_wraps_from_outside_the_checkout(wheel_site):
    """models/ and the sample clouds are inside the wheel as drake_continuum/models and
    drake_continuum/clouds; unpacked away from the checkout, `wrap` and `demo` run there."""
    wheel, site, run = wheel_site
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder, package in ((ROOT / "models", "models"), (ROOT / "real" / "data", "clouds")):
        for f in sorted(folder.iterdir()):
            if f.is_file():
                assert f"drake_continuum/{package}/{f.name}" in names, \
                    f"{f.name} not in {wheel.name}"
    _check_metadata(zipfile.ZipFile(wheel))
    env = dict(os.environ, PYTHONPATH=str(site))
    where = subprocess.run([sys.executable, "-c", "import drake_continuum.kinematics.arm as a; "
                            "import drake_continuum.perception.cloud as c; "
                            "print(a.__file__); print(a.DEFAULT_ARM_YAML); "
                            "print(c.SAMPLE_CLOUDS)"], cwd=run, env=env,
                           capture_output=True, text=True, check=True).stdout.split()
    assert all(Path(p).is_relative_to(site) for p in where), where
    out = subprocess.run([sys.executable, "-m", "drake_continuum.cli", "wrap",
                          str(site / "drake_continuum" / "models" / "mug.obj"), "--plane", "0",
                          "--set", "wrap.theta_deg=90", "--json"],
                         cwd=run, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["status"] == "complete" and summary["tip_rotation_deg"] >= 90
    out = subprocess.run([sys.executable, "-m", "drake_continuum", "demo", "--out", "demo",
                          "--json"], cwd=run, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["contacts"] and (run / "demo" / "demo.png").is_file()


@pytest.mark.slow
def test_wheel_compares_the_sample_clouds_from_outside_the_checkout(wheel_site):
    """Fig. 8's comparison on the sample clouds the wheel holds: one row and figure a cloud,
    the tip found within a centimetre (an empty table was possible before)."""
    _, site, run = wheel_site
    script = ("import json; from drake_continuum.perception.comparison import "
              "compare_shipped_clouds as c; print(json.dumps(c('fig8')))")
    out = subprocess.run([sys.executable, "-c", script], cwd=run, capture_output=True,
                         text=True, env=dict(os.environ, PYTHONPATH=str(site)))
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)["clouds"]
    assert sorted(r["cloud"] for r in rows) == sorted(
        p.name for p in (ROOT / "real" / "data").glob("*.pcd"))
    assert all(r["tip_error_mm"] < 10 and (run / "fig8" / r["png"]).is_file() for r in rows)


def test_sample_clouds_missing_are_an_error_not_an_empty_table(tmp_path):
    from drake_continuum.errors import MissingFileError
    from drake_continuum.perception.comparison import compare_shipped_clouds
    with pytest.raises(MissingFileError, match=f"{tmp_path}: no sample cloud"):
        compare_shipped_clouds(tmp_path / "out", data_dir=tmp_path)
    (tmp_path / "a.pcd").write_text("")
    with pytest.raises(MissingFileError, match="a.json: the sidecar of a.pcd is missing"):
        compare_shipped_clouds(tmp_path / "out", data_dir=tmp_path)


def _check_metadata(wheel: zipfile.ZipFile) -> None:
    """The wheel's metadata (issue 17): an SPDX licence matching the LICENSE file it ships,
    Dask only in the `cluster` extra, the Python range of the pinned Drake's wheels."""
    from importlib.metadata import metadata
    (meta_name,) = [n for n in wheel.namelist() if n.endswith(".dist-info/METADATA")]
    meta = wheel.read(meta_name).decode()
    fields = [line.split(": ", 1) for line in meta.split("\n\n", 1)[0].splitlines()
              if ": " in line]
    get = lambda key: [v for k, v in fields if k == key]  # noqa: E731
    assert get("License-Expression") == ["BSD-3-Clause"]
    assert get("License-File") == ["LICENSE"]
    (licence,) = [n for n in wheel.namelist() if n.endswith("/LICENSE")]
    text = wheel.read(licence).decode()
    assert text.startswith("BSD 3-Clause License\n") and "Neither the name" in text
    assert not any("License ::" in c for c in get("Classifier"))  # the expression says it
    dask = [r for r in get("Requires-Dist") if r.startswith("dask")]
    assert dask == ['dask[distributed]>=2024.1; extra == "cluster"'], dask
    # The lower bound is Drake's own (its wheel's metadata); the upper bound is above the
    # newest CPython it has wheels for (cp314 for 1.51.1).
    drake = metadata("drake")
    assert drake["Version"].startswith("1.51.")
    (python,) = get("Requires-Python")
    assert set(python.split(",")) == {drake["Requires-Python"], "<3.15"}, python
    assert drake["Requires-Python"] == ">=3.10"
    assert sorted(c.rsplit(":: ", 1)[1] for c in get("Classifier")
                  if re.fullmatch(r"Programming Language :: Python :: 3\.\d+", c)) == \
        ["3.10", "3.11", "3.12", "3.13", "3.14"]


def test_cli_prints_user_errors_as_one_line_and_bugs_with_a_note(monkeypatch, capsys):
    from drake_continuum import cli
    from drake_continuum.errors import InputError

    def run_with(exc):
        def run(args):
            raise exc
        commands = [(name, add, run if name == "demo" else go) for name, add, go in cli.COMMANDS]
        monkeypatch.setattr(cli, "COMMANDS", commands)

    run_with(InputError("cup.obj: holds no triangles"))
    assert cli.main(["demo"]) == 1
    assert capsys.readouterr().err == "drake-continuum demo: error: cup.obj: holds no triangles\n"
    run_with(KeyError("s"))
    assert cli.main(["demo"]) == cli.INTERNAL_ERROR
    err = capsys.readouterr().err
    assert "internal error: KeyError" in err and "report it" in err and "Traceback" not in err
    assert cli.main(["-v", "demo"]) == cli.INTERNAL_ERROR
    assert "Traceback" in capsys.readouterr().err


def test_cli_refuses_a_bad_setting_naming_the_key(capsys):
    from drake_continuum import cli
    from drake_continuum.kinematics.arm import MODELS_DIR
    assert cli.main(["wrap", str(MODELS_DIR / "mug.obj"), "--plane", "0",
                     "--set", "wrap.ik.tolerance=-0.01"]) == 1
    assert capsys.readouterr().err == ("drake-continuum wrap: error: --set "
                                       "'wrap.ik.tolerance=-0.01': wrap.ik.tolerance: "
                                       "must be in (0, 0.1] m, got -0.01\n")
