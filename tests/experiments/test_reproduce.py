"""`reproduce` end to end on a tiny subset: every report section holds numbers, the HTML
report's images load in a real browser, and a second run resumes instead of recomputing."""

import json
import os
import re
import resource
from dataclasses import replace

import pytest

import drake_continuum.experiments.reproduce as reproduce_module
from drake_continuum.config import load_config
from drake_continuum.experiments.reproduce import (
    PLACEMENTS,
    QUICK_PLACEMENTS,
    STEPS,
    RunSettings,
    held_out_kinds,
    reproduce,
)
from drake_continuum.experiments.timing import run_work, work_total

CATEGORIES = ("bottle", "cup", "mug")  # three of Table II's, two alike (a multi-class problem)
SMALL = ("planes.alpha_deg=90", "wrap.theta_deg=180")  # the run fixture's planes and wraps
CHROMIUM = "/usr/bin/chromium"
RUN_CPU = {}  # the run fixture's CPU seconds, this process's and its children's
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                 "--disable-background-networking", "--disable-component-update",
                 "--no-first-run"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    # Tiny: 3 categories of 4 objects (2 to train on in a split: the classifier's
    # calibration needs 2 a category), the 4 planes of alpha = 90 deg, wraps ending at a
    # tip turned 180 deg (the paper's 270: every section still has its wraps), 3 splits,
    # short searches; placed copies (one to train on, one on another side) of 1 object a
    # category.
    # One process: two workers take a sixth more CPU (their starts, a second pool for the
    # camera study); the run's pool is the redo test's. The camera study sees 1 object of
    # each of 2 categories (the quick run's 4 of 2): its fits are most of its time.
    config = load_config(overrides=[*SMALL, "active.n_simulations=40"])
    settings = RunSettings(out=out, quick=True, per_category=4, splits=3, workers=1,
                           config=config, categories=CATEGORIES, placements="train=1,rest=1",
                           placed_per_category=1)
    with pytest.MonkeyPatch.context() as patch:  # for the module's later runs too
        patch.setattr(reproduce_module, "QUICK_OBSERVED", (1, 2))
        cpu0 = _cpu_s()
        report = reproduce(settings)
        RUN_CPU["s"] = _cpu_s() - cpu0
        yield out, settings, report


def _cpu_s() -> float:
    """CPU seconds of this process and its ended children, as the kernel counts them."""
    return sum(u.ru_utime + u.ru_stime for u in (resource.getrusage(resource.RUSAGE_SELF),
                                                 resource.getrusage(resource.RUSAGE_CHILDREN)))


def test_a_quick_run_tests_its_side_copies_where_it_places_no_rest_copy():
    """The quick placements wrap no `rest` copy: active recognition tests the held-out
    objects' side copies (side0 lies on the same side as rest0: test_placement) instead;
    a run that places rest copies does not test its training kinds."""
    assert "rest" not in QUICK_PLACEMENTS and "side=1" in QUICK_PLACEMENTS
    assert set(held_out_kinds(QUICK_PLACEMENTS)) >= {"turned", "side"}
    assert "side" not in held_out_kinds(PLACEMENTS)
    assert held_out_kinds("train=1,rest=1") == ("turned", "rest", "lying", "nudged")


def test_report_holds_every_section_with_numbers(run):
    out, _, report = run
    md = report.read_text()
    for heading in ("## Headline", "## Dataset", "## Wraps (Fig. 5, Table I)",
                    "## Classification (Fig. 7)", "## Active recognition (Table II)",
                    "## Point clouds against simulated wraps (Fig. 8)",
                    "## Objects placed as a robot meets them",
                    "## Recognition from what the camera sees of the arm", "## Times"):
        section = md.split(heading, 1)[1].split("\n## ", 1)[0]
        assert re.search(r"\d", section), f"{heading} holds no number"
    assert "75.9 %" in md and "74.7 %" in md  # the paper's figures beside ours
    summary = json.loads((out / "summary.json").read_text())
    cls = summary["classification"]
    assert cls["n_objects"] == 12 and cls["n_splits"] == 3
    assert 0.0 <= cls["accuracy_mean"] <= 1.0
    assert set(summary["active"]["policies"]) == {"mcts", "greedy", "random"}
    observed = summary["observed"]  # the camera study: four conditions, each at the stop too
    assert observed["n_objects"] == 2 and set(observed["active"]) == set(observed["conditions"]
                                                                         ) - {"exact_touch_only"}
    assert 0 < observed["conditions"]["one_view"]["cpu_s_median"] < 30
    assert len(summary["real"]["clouds"]) >= 1
    # the shipped clouds are the simulator's, and the report says so
    assert {r["capture"] for r in summary["real"]["clouds"]} == {"simulated"}
    assert "clouds are simulated, not captured" in md
    for step in STEPS:
        assert (out / f"{step}.done.json").exists()
    # Where the time went: every step's wall time, the work by kind in CPU seconds.
    times = md.split("## Times", 1)[1]
    assert "| step | wall s |" in times and "| work | CPU s |" in times
    assert all(f"| {step} |" in times for step in STEPS)
    assert "| camera |" in times and "of which ik" in times and "| training |" in times
    work = summary["collect"]["work_s"]
    assert work["wraps"] > work["ik"] > 0 and work["camera"] > 0
    # The work by kind is the run's CPU time (the report written after the steps aside)
    assert work_total(run_work(summary)) == pytest.approx(RUN_CPU["s"], rel=0.05)


def test_placed_objects_are_reported_and_the_recommended_models_saved(run):
    """Placed copies of both datasets are evaluated by kind, chords and triangles; OUT/model
    and OUT/active-model load, trained on the originals and their training placements."""
    from drake_continuum.active.training import load_active_model
    from drake_continuum.learning.model import load_model
    out, _, report = run
    summary = json.loads((out / "summary.json").read_text())
    for figures in (summary["placements"], summary["second"]):
        for method in ("chords", "triangles"):
            kinds = figures["results"][method]["kinds"]
            assert set(kinds) == {"generated", "rest", "train"}
            assert all(0.0 <= k["accuracy_mean"] <= 1.0 for k in kinds.values())
            assert kinds["generated"]["n_records"] == 12
            assert kinds["rest"]["n_records"] == kinds["train"]["n_records"] == 3
        assert figures["train_kinds"] == ["generated", "train"]
    assert summary["second"]["seed"] == 1
    assert summary["placements"]["n_trained"] == 12 + 3  # originals + training copies
    assert summary["placements"]["collect"]["n_failed"] == 0
    assert summary["placements"]["work_s"]["wraps"] > 0
    assert summary["placements"]["work_s"]["dataset"] > 0  # placing the copies
    assert load_model(out / "model").info["n_objects"] == 15
    assert load_active_model(out / "active-model").observations.n_planes == 4
    placed = summary["active_placed"]["policies"]["mcts"]
    assert set(placed["by_kind"]) == {"rest"}
    md = report.read_text()
    assert "second dataset (seed 1" in md and "on its likeliest other side" in md


def test_a_collection_run_ahead_raises_its_error_in_its_step():
    from drake_continuum.experiments.schedule import Ahead

    def fails():
        raise OSError("disk full")
    ahead = Ahead(fails)
    ahead.start()
    with pytest.raises(OSError, match="disk full"):
        ahead.take()
    done = Ahead(lambda: 42)
    done.start()
    assert done.take() == 42


def test_each_step_runs_once_after_the_steps_it_reads():
    """The order this process runs the steps in: every step once, each after the steps
    whose outputs it reads (STEP_AFTER)."""
    from drake_continuum.experiments.reproduce import _RUN_ORDER, STEP_AFTER
    assert sorted(_RUN_ORDER) == sorted(STEPS)
    for step, before in STEP_AFTER.items():
        assert all(_RUN_ORDER.index(b) < _RUN_ORDER.index(step) for b in before), step


def test_work_not_started_is_none_and_work_kept_is_taken_once():
    from concurrent.futures import Future

    from drake_continuum.experiments import schedule
    assert schedule.take("nothing") is None and schedule.take("nothing", 7) == 7
    schedule.keep("queued", {"tasks": []})
    assert schedule.take("queued") == {"tasks": []} and schedule.take("queued") is None
    done = Future()
    done.set_result(3)
    schedule.keep("future", done)
    assert schedule.take("future") == 3


def test_a_collection_ends_when_its_executor_cancels_what_is_queued():
    """A pool stopped on Ctrl-C (shutdown with cancel_futures) cancels its queued futures
    without waking `concurrent.futures.wait`; the collection run ahead, in a thread of its
    own, must still end, each cancelled object recorded as failed (a rerun redoes it)."""
    import threading
    from concurrent.futures import Future

    from drake_continuum.experiments.collect import _run

    class Cancelling:  # cancels every task it is given, as the stopped pool does
        def submit(self, fn, *args):
            future = Future()
            future.cancel()
            return future

    failed = {}

    class Folder:
        def on_error(self, oid, message):
            failed[oid] = message

        def on_result(self, result):
            raise AssertionError("a cancelled object has no result")

    tasks = [{"object_id": "cup_000"}, {"object_id": "mug_000"}]
    thread = threading.Thread(target=_run, args=(Cancelling(), tasks, Folder()), daemon=True)
    thread.start()
    thread.join(timeout=20)
    assert not thread.is_alive()
    assert set(failed) == {"cup_000", "mug_000"}
    assert all(m.startswith("CancelledError") for m in failed.values())


def test_a_quick_run_places_the_first_objects_of_each_category(tmp_path):
    """A quick run places QUICK_PLACED_PER_CATEGORY objects a category unless told, and
    records it; a full run places every object and records nothing."""
    from drake_continuum.experiments.settings import QUICK_PLACED_PER_CATEGORY, settings_record
    quick = RunSettings(out=tmp_path, quick=True)
    assert quick.effective_placed_per_category == QUICK_PLACED_PER_CATEGORY == 2
    assert settings_record(quick)["placed_per_category"] == 2
    told = RunSettings(out=tmp_path, quick=True, placed_per_category=3)
    assert told.effective_placed_per_category == 3
    full = RunSettings(out=tmp_path)
    assert full.effective_placed_per_category is None
    assert "placed_per_category" not in settings_record(full)


def test_results_page_is_written_beside_the_report(run):
    """OUT/results.md holds the run's headline accuracy, names the package version that made
    each section and links the images where the run wrote them."""
    from drake_continuum import __version__
    out, _, _ = run
    md = (out / "results.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert f"**{100 * summary['classification']['accuracy_mean']:.1f} %" in md
    assert md.count(f"(drake-continuum {__version__}, ") >= 4
    assert "](classification/confusion.png)" in md and "## Point clouds against" in md


def test_second_run_resumes(run):
    out, settings, _ = run
    before = {step: (out / f"{step}.done.json").stat().st_mtime_ns for step in STEPS}
    reproduce(settings)
    after = {step: (out / f"{step}.done.json").stat().st_mtime_ns for step in STEPS}
    assert before == after


def test_other_settings_are_refused(run):
    out, settings, _ = run
    with pytest.raises(ValueError, match="other settings"):
        reproduce(RunSettings(out=out, quick=True, per_category=5, splits=3,
                              config=settings.config))


def test_a_section_the_folder_did_not_record_counts_as_its_defaults(tmp_path):
    """A run recorded before the configuration had a section matches a run with that
    section's defaults, and is refused with another value, naming the key."""
    from drake_continuum.experiments.reproduce import _check_settings
    from drake_continuum.experiments.settings import settings_record
    settings = settings_record(RunSettings(out=tmp_path, quick=True))
    older = json.loads(json.dumps(settings))
    del older["config"]["observed"]
    (tmp_path / "settings.json").write_text(json.dumps(older))
    _check_settings(tmp_path, settings, redo=False)
    settings["config"]["observed"]["tie_width"] = 0.002
    with pytest.raises(ValueError, match=r"config.observed.tie_width \(0.003 -> 0.002\)"):
        _check_settings(tmp_path, settings, redo=False)


@pytest.mark.skipif(not os.path.exists(CHROMIUM),
                    reason=f"{CHROMIUM} is absent (apt-get install -y chromium; "
                           "scripts/setup.sh installs it as root)")
def test_html_report_images_load_in_chromium(run):
    out, _, _ = run
    sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            errors = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto((out / "report.html").as_uri())
            page.wait_for_load_state("load")
            sizes = page.eval_on_selector_all(
                "img", "imgs => imgs.map(i => [i.getAttribute('src'), i.complete, "
                       "i.naturalWidth])")
        finally:
            browser.close()
    assert len(sizes) >= 5, sizes
    broken = [src for src, complete, width in sizes if not complete or width == 0]
    assert not broken, f"images that did not load: {broken}"
    assert not errors


def test_report_says_which_clouds_are_simulated():
    from drake_continuum.experiments.report import clouds_table
    row = {"cloud": "a.pcd", "tip_error_mm": 1.5, "png": "a.png"}
    md = clouds_table({"clouds": [{**row, "capture": "simulated"},
                                  {**row, "cloud": "b.pcd", "capture": "real"}]})
    assert "1 of these 2 clouds are simulated, not captured" in md
    assert "| a.pcd | simulated | 1.5 |" in md and "| b.pcd | real | 1.5 |" in md
    md = clouds_table({"clouds": [{**row, "capture": "real"}]})
    assert "simulated" not in md


def test_report_lists_the_objects_most_often_wrong():
    """The report's table of misclassified objects: the most often wrong first (as
    Evaluation.misclassified orders them), at most `top` rows, and the command to draw one;
    nothing when no object was ever wrong."""
    from drake_continuum.experiments.report import _misclassified

    rows = [{"object_id": f"cup_{i:03d}", "category": "cup", "wrong": 10 - i, "tested": 10,
             "as": {"mug": 10 - i}} for i in range(10)]
    md = _misclassified(rows, top=3)
    assert "10 were wrong at least once" in md
    assert md.index("| cup_000 | cup | 10 / 10 | mug 10 |") < md.index("| cup_002 |")
    assert "cup_003" not in md.split("To see one")[0]
    assert "show-wraps wraps cup_000" in md
    assert _misclassified([]) == ""


def test_other_settings_are_named_and_redo_redoes_only_the_steps_they_change(run, tmp_path):
    out, settings, _ = run
    config = load_config(overrides=[*SMALL, "active.n_simulations=40", "active.horizon=3"])
    changed = replace(settings, config=config)
    with pytest.raises(ValueError, match=r"config\.active\.horizon \(5 -> 3\).*--redo.*"
                                         r"\(active, active_placed, observed\)"):
        reproduce(changed)
    before = {step: (out / f"{step}.done.json").stat().st_mtime_ns for step in STEPS}
    reproduce(replace(changed, redo=True))
    after = {step: (out / f"{step}.done.json").stat().st_mtime_ns for step in STEPS}
    assert [s for s in STEPS if before[s] != after[s]] == ["active", "active_placed",
                                                           "observed"]
    recorded = json.loads((out / "settings.json").read_text())
    assert recorded["config"]["active"]["horizon"] == 3
    assert json.loads((out / "active" / "active.json").read_text())["params"]["horizon"] == 3
    # A classifier setting and other placement counts in one redo, on two workers (not a
    # setting): every wrap still asked for (the copies drawn as before, the second
    # dataset's objects) is resumed, not made again; the copies no longer asked for are
    # removed (not evaluated), the new ones are wrapped on the run's pool; every step that
    # reads the classifier is redone (the placement count's steps are among them:
    # test_steps_a_change_invalidates).
    wraps = sorted(p for folder in ("placed_wraps", "second/wraps", "second/placed_wraps")
                   for p in (out / folder).glob("*.npz"))
    assert len(wraps) > 12
    kept = {p: p.stat().st_mtime_ns for p in wraps if "@rest" not in p.name}
    assert any("@train" in p.name for p in kept) and any("second/wraps" in str(p) for p in kept)
    assert len(kept) < len(wraps)  # the rest copies, no longer asked for
    config = load_config(overrides=[*SMALL, "active.n_simulations=40", "active.horizon=3",
                                    "classifier.svm_c=2"])
    pooled = replace(changed, config=config, redo=True, placements="train=1,lying=1",
                     workers=2)
    reproduce(pooled)
    again = {step: (out / f"{step}.done.json").stat().st_mtime_ns for step in STEPS}
    assert [s for s in STEPS if again[s] != after[s]] == [
        "classification", "active", "real", "placements", "active_placed", "second",
        "observed"]
    assert {p: p.stat().st_mtime_ns for p in kept} == kept
    for folder in ("placed_wraps", "second/placed_wraps"):
        names = [p.name for p in (out / folder).glob("*.npz")]
        assert not any("@rest" in n for n in names)
        assert sum("@lying0" in n for n in names) == sum("@train0" in n for n in names) == 3
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["placements"]["results"]["chords"]["kinds"]) == {"generated", "lying",
                                                                       "train"}
    assert json.loads((out / "settings.json").read_text())["config"]["classifier"]["svm_c"] == 2
    _assert_wrapped_as_in_one_process(out, pooled, tmp_path)


def _assert_wrapped_as_in_one_process(out, pooled, tmp_path):
    """The run's pool wrapped the new placed copies while the steps after `collect` ran (its
    collection run ahead): the same wraps as placing and collecting them in one process in
    the placements step, array for array but the time."""
    import numpy as np

    from drake_continuum.experiments.reproduce import _placed_collection
    summary = json.loads((out / "summary.json").read_text())
    assert summary["placements"]["collect"]["workers"] == 2
    assert summary["placements"]["collect"]["n_failed"] == 0
    (tmp_path / "dataset").symlink_to(out / "dataset")
    # The new copies alone: a kind's copies are drawn as with the other kinds.
    inline = replace(pooled, out=tmp_path, workers=1, redo=False, placements="lying=1")
    report, _ = _placed_collection(inline, tmp_path, inline.seed, where=None)
    assert report.workers == 1 and len(report.done) == 3  # 3 objects' lying copies
    for mine in sorted((tmp_path / "placed_wraps").glob("*.npz")):
        with np.load(mine) as a, np.load(out / "placed_wraps" / mine.name) as b:
            assert set(a.files) == set(b.files)
            for key in a.files:
                x, y = a[key], b[key]
                if key.endswith("scalars"):  # plane, tip rotation, queries, time, ...
                    x, y = np.delete(x, 3), np.delete(y, 3)
                np.testing.assert_array_equal(x, y, err_msg=f"{mine.name} {key}")


def test_steps_a_change_invalidates():
    from drake_continuum.experiments.reproduce import outputs_to_remove, steps_to_redo
    assert steps_to_redo(["config.classifier.svm_c"]) == ["classification", "active", "real",
                                                         "placements", "active_placed",
                                                         "second", "observed"]
    assert steps_to_redo(["config.wrap.delta"]) == list(STEPS[2:])
    assert steps_to_redo(["seed"]) == list(STEPS)
    assert steps_to_redo(["splits"]) == ["classification", "placements", "active_placed",
                                         "second", "observed"]
    assert steps_to_redo(["placements"]) == ["placements", "active_placed", "second"]
    assert steps_to_redo(["placed_per_category"]) == ["placements", "active_placed", "second"]
    assert steps_to_redo(["second_dataset"]) == ["second"]
    assert steps_to_redo(["config.observed.tie_width"]) == ["observed"]
    assert steps_to_redo(["config"]) == list(STEPS[2:])  # a folder from before settings recorded it
    # A redo removes the meshes and wraps of placed copies and of the second dataset only
    # when a setting that makes them changed.
    assert outputs_to_remove("placements", ["config.classifier.svm_c"]) == (
        "placements", "model", "active-model")
    assert outputs_to_remove("second", ["splits"]) == ("second/classification",
                                                       "second/placements")
    for key in ("config.wrap.delta", "seed", "config.arm"):
        assert "placed_wraps" in outputs_to_remove("placements", [key])
        assert "second/wraps" in outputs_to_remove("second", [key])
    # Other placement counts keep the copies (collect.prune_stale drops those not placed).
    assert outputs_to_remove("placements", ["placements"]) == ("placements", "model",
                                                               "active-model")
    assert "second/wraps" in outputs_to_remove("second", ["second_dataset"])


def test_a_bad_setting_stops_before_any_step_and_a_failed_step_is_not_marked(tmp_path, capsys):
    from drake_continuum.cli import main
    from drake_continuum.experiments.reproduce import _step
    for value, says in (("abc", "expected a number, got 'abc'"),
                        ("-1", r"must be in (0, 0.1] m")):
        assert main(["reproduce", "--quick", "--out", str(tmp_path / "r"),
                     "--set", f"wrap.delta={value}"]) == 1
        err = capsys.readouterr().err
        assert "wrap.delta" in err and says in err and err.count("\n") == 1
    assert not (tmp_path / "r").exists()

    def fails():
        raise ValueError("half done")
    with pytest.raises(ValueError, match="half done"):
        _step(tmp_path, "collect", fails)
    assert not (tmp_path / "collect.done.json").exists()


def test_a_run_without_the_second_dataset_says_so(tmp_path):
    from drake_continuum.experiments.report import _placed_section
    placed = {"train_kinds": ["generated"], "table": "placements/placements.md",
              "model": "model", "active_model": "active-model"}
    text = _placed_section(tmp_path, {"placements": placed, "second": {"skipped": True}})
    assert "### A second dataset" in text and "`--no-second-dataset`" in text
    assert "second dataset" not in _placed_section(tmp_path, {"placements": placed})


def test_a_run_without_the_camera_study_says_so_and_records_it(tmp_path):
    from drake_continuum.experiments.report import observed_section
    from drake_continuum.experiments.reproduce import RunSettings, _observed, steps_to_redo
    from drake_continuum.experiments.settings import settings_record
    settings = RunSettings(out=tmp_path, quick=True, observed=False)
    assert _observed(settings) == {"skipped": True}
    assert not (tmp_path / "observed").exists()
    assert "`--no-observed`" in observed_section({"skipped": True})
    assert settings_record(settings)["observed"] is False
    assert "observed" not in settings_record(RunSettings(out=tmp_path, quick=True))
    assert steps_to_redo(["observed"]) == ["observed"]


def test_a_run_of_some_categories_generates_those_with_the_papers_counts(tmp_path, capsys):
    """`--categories`: the chosen categories only, each with the paper's count (cup 10, mug
    32) or per_category when quick; recorded, named in the command, and a change of it
    redoes the run from the dataset on; a bad list is refused by name before any step."""
    from drake_continuum.cli import main
    from drake_continuum.errors import InputError
    from drake_continuum.experiments.reproduce import _dataset_counts, steps_to_redo
    from drake_continuum.experiments.settings import run_command, settings_record
    full = RunSettings(out=tmp_path, categories=["mug", "cup"])
    assert full.categories == ("mug", "cup") and _dataset_counts(full) == {"cup": 10, "mug": 32}
    quick = RunSettings(out=tmp_path, quick=True, per_category=5, categories=("mug", "cup"))
    assert _dataset_counts(quick) == {"cup": 5, "mug": 5}
    record = settings_record(quick)
    assert record["categories"] == ["mug", "cup"]
    assert "--categories mug,cup" in run_command(record)
    assert "categories" not in settings_record(RunSettings(out=tmp_path))
    assert steps_to_redo(["categories"])[:3] == ["dataset", "gallery", "collect"]
    for names, says in ((("mug", "cat"), "unknown cat"), (("mug",), "at least two"),
                        (("mug", "mug"), "each once")):
        with pytest.raises(InputError, match=says):
            RunSettings(out=tmp_path, categories=names)
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "r"),
                 "--categories", "mug,dog"]) == 1
    err = capsys.readouterr().err
    assert "--categories: unknown dog" in err and err.count("\n") == 1
    assert not (tmp_path / "r").exists()
