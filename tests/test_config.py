"""The experiment configuration is the one source of the parameters' values."""

from dataclasses import replace

import numpy as np
import pytest

from drake_continuum.active.params import ActiveParams
from drake_continuum.config import (
    DEFAULT_CONFIG,
    Config,
    ObservedParams,
    config_from_tree,
    config_to_tree,
    load_config,
    tree_difference,
)
from drake_continuum.errors import ConfigError
from drake_continuum.features.chords import ChordParams
from drake_continuum.learning.pipeline import ClassifierParams
from drake_continuum.wrapping.wrap import WrapParams


def test_shipped_config_equals_the_documented_defaults():
    c = load_config()
    assert c.wrap == WrapParams()
    assert c.chords == ChordParams()
    assert c.classifier == ClassifierParams()
    assert c.active == ActiveParams()
    assert c.alpha_deg == 22.5
    # The paper's values (section V-A), in SI units.
    assert np.isclose(c.wrap.theta, np.radians(270))
    assert np.isclose(c.wrap.d_kappa, 1e-3 / 1e-2)
    assert np.isclose(c.wrap.d_s, 1e-4 * 1e-2)
    assert np.isclose(c.wrap.delta, 0.1 * 1e-2)
    assert c.active.horizon == 5


def test_the_scenarios_defaults_are_the_shipped_files():
    """One set of defaults: the dataclasses' and models/config.yaml's (with models/arm.yaml)."""
    from drake_continuum.config import Config
    assert Config() == load_config()
    assert Config().planes.bearing == "object" and Config().planes.centre == "camera"


def test_overrides_and_their_errors(tmp_path):
    c = load_config(overrides=["wrap.delta=0.002", "wrap.ik.tolerance=0.005",
                               "active.horizon=3", "planes.alpha_deg=30"])
    assert (c.wrap.delta, c.wrap.ik.tolerance, c.active.horizon, c.alpha_deg) == \
        (0.002, 0.005, 3, 30.0)
    with pytest.raises(ValueError, match="no key 'deltaa'"):
        load_config(overrides=["wrap.deltaa=1"])
    with pytest.raises(ValueError, match="expected section.key=value"):
        load_config(overrides=["wrap.delta"])
    bad = tmp_path / "c.yaml"
    bad.write_text("arm: arm.yaml\nwraps:\n  delta: 0.002\n")  # a misspelt section
    with pytest.raises(ValueError, match=f"{bad}: unknown section wraps \\(known: arm, "):
        load_config(bad)
    bad.write_text("arm: arm.yaml\nwrap:\n  delta: 0.002\n")  # the others' defaults
    assert load_config(bad) == Config(wrap=WrapParams(delta=0.002))


@pytest.mark.parametrize("assignment, says", [
    ("wrap.delta=abc", "wrap.delta: expected a number, got 'abc'"),
    (r"wrap.delta=-1", r"wrap.delta: must be in \(0, 0.1\] m, got -1"),
    ("wrap.theta_deg=.nan", "wrap.theta_deg: must be a finite number, got nan"),
    ("wrap.start_lengths=[0.1, -0.1]", r"wrap.start_lengths: must be in \(0, 1\] m"),
    ("wrap.start_lengths=0.1", "wrap.start_lengths: expected a list of numbers, got 0.1"),
    ("wrap.ik.mode=fastest", "wrap.ik.mode: must be one of 'auto', 'exact', 'least_squares'"),
    ("wrap.method=quick", "wrap.method: must be one of 'fast', 'reference'"),
    ("planes.centre=table", "planes.centre: must be one of 'camera', 'mark'"),
    ("wrap.ik=3", "wrap.ik: expected a mapping of settings, got 3"),
    ("classifier.coarse=8", r"classifier.coarse: must be at most bins \(7\), got 8"),
    ("wrap.max_iterations=2.5", "wrap.max_iterations: expected a whole number"),
    ("planes.both_directions=1", "planes.both_directions: expected true or false"),
    ("planes.alpha_deg=0", r"planes.alpha_deg: must be in \(0, 90\]"),
    ("chords.frame=body", "chords.frame: must be one of 'world', 'wrap'"),
    ("classifier.variance=1.5", r"classifier.variance: must be in \(0, 1\]"),
    ("active.horizon=0", "active.horizon: must be from 1 to 100"),
    ("active.discount=true", "active.discount: expected a number, got True"),
])
def test_a_bad_value_is_refused_naming_its_key(assignment, says):
    with pytest.raises(ConfigError, match=says):
        load_config(overrides=[assignment])


def test_a_bad_value_given_by_set_names_the_set_not_the_file(tmp_path):
    """The file a --set overrides holds no error: the refusal names the --set."""
    mine = tmp_path / "mine.yaml"
    mine.write_text("planes:\n  alpha_deg: 90\n")
    for path, overrides, says in [
            (None, ["wrap.delta=abc"], "--set 'wrap.delta=abc': wrap.delta: expected a number"),
            (mine, ["wrap.ik.mode=fastest"], "--set 'wrap.ik.mode=fastest': wrap.ik.mode: must"),
            (mine, ["wrap.delta=0.002", "wrap.delta=-1"], "--set 'wrap.delta=-1': wrap.delta"),
            (None, [f"arm={mine}"], f"--set 'arm={mine}': arm description {mine}: ")]:
        with pytest.raises(ConfigError) as e:
            load_config(path, overrides=overrides)
        assert str(e.value).startswith(says), str(e.value)
    mine.write_text("planes:\n  alpha_deg: 900\n")  # the file's own error still names it
    with pytest.raises(ConfigError, match=f"^configuration {mine}: planes.alpha_deg: "):
        load_config(mine, overrides=["wrap.delta=0.002"])


def test_a_models_file_lays_its_settings_on_those_the_model_records(tmp_path):
    """classify/recognize --config FILE: the file's settings on top of the model's; a
    section or key it leaves out keeps the recorded one (the model's arm and planes), not
    the shipped default."""
    from drake_continuum.config import config_to_tree, model_config
    five = DEFAULT_CONFIG.with_name("arm_5sections.yaml")
    trained = load_config(overrides=[f"arm={five}", "planes.alpha_deg=90", "wrap.delta=0.002",
                                     "active.horizon=3"])
    info = {"settings": {"config": config_to_tree(trained)}}
    mine = tmp_path / "search.yaml"
    mine.write_text("active:\n  n_simulations: 50\nwrap:\n  ik: {tolerance: 0.005}\n")
    cfg, warnings = model_config(info, mine)
    assert cfg.arm().n_sections == 5 and cfg.alpha_deg == 90.0 and cfg.wrap.delta == 0.002
    assert (cfg.active.horizon, cfg.active.n_simulations) == (3, 50)
    assert cfg.wrap.ik.tolerance == 0.005 and cfg.wrap.ik.mode == trained.wrap.ik.mode
    assert warnings == ["wraps differ from the training collection's in wrap.ik.tolerance "
                        "(0.01 -> 0.005)"]
    (tmp_path / "arm.yaml").write_text(DEFAULT_CONFIG.with_name("arm.yaml").read_text())
    mine.write_text("arm: arm.yaml\nplanes:\n")  # an arm the file names replaces the model's
    cfg, warnings = model_config(info, mine)
    assert cfg.arm().n_sections == 3 and cfg.alpha_deg == 90.0
    assert "wraps differ from the training collection's in arm.n_sections (5 -> 3)" in warnings


def test_unknown_keys_in_a_file_are_refused_naming_file_and_key(tmp_path):
    text = DEFAULT_CONFIG.read_text().replace("  delta: 1.0e-3", "  delta: 1.0e-3\n  deltaa: 1")
    path = tmp_path / "c.yaml"
    path.write_text(text.replace("arm: arm.yaml", f"arm: {DEFAULT_CONFIG.parent / 'arm.yaml'}"))
    with pytest.raises(ConfigError, match=rf"{path}: wrap.deltaa: unknown key"):
        load_config(path)


def test_every_field_of_the_parameter_classes_is_read_and_recorded():
    """Loading is generic over the dataclasses: each field appears in the recorded tree
    (radians as <name>_deg), and the tree gives back the same parameters."""
    from dataclasses import fields

    from drake_continuum.kinematics.ik import IKOptions
    c = load_config()
    tree = config_to_tree(c)
    for section, cls in (("wrap", WrapParams), ("chords", ChordParams),
                         ("classifier", ClassifierParams), ("active", ActiveParams)):
        for f in fields(cls):
            assert f.name in tree[section] or f"{f.name}_deg" in tree[section], (section, f)
    assert {f.name for f in fields(IKOptions)} == set(tree["wrap"]["ik"])
    back = config_from_tree(tree)
    assert (back.wrap, back.chords, back.classifier, back.active, back.planes) == \
        (c.wrap, c.chords, c.classifier, c.active, c.planes)
    assert config_to_tree(back)["arm"] == config_to_tree(c)["arm"]
    assert np.array_equal(back.arm().base_rotation, c.arm().base_rotation)


def test_a_collections_recorded_parameters_give_back_its_wrap_settings():
    from drake_continuum.experiments.collection import collection_tree, run_params
    params = WrapParams(theta_deg=200.0, delta=0.002)
    shipped = load_config()
    scenario = replace(shipped, wrap=params,
                       planes=replace(shipped.planes, alpha_deg=30.0, both_directions=True,
                                      bearing="world", centre="mark"))
    tree = config_to_tree(shipped)
    tree.update(collection_tree(run_params(scenario)))
    c = config_from_tree(tree)
    assert c.wrap == params and c.planes == scenario.planes
    assert tree_difference(config_to_tree(shipped), tree) == [
        "planes.alpha_deg (22.5 -> 30.0)",
        "planes.bearing ('object' -> 'world')",
        "planes.both_directions (False -> True)",
        "planes.centre ('camera' -> 'mark')",
        "wrap.delta (0.001 -> 0.002)", "wrap.theta_deg (270.0 -> 200.0)"]


def older_layout(params: dict) -> dict:
    """Recorded run parameters as a collection made while WrapParams held its angles in
    radians stored them (theta, stall_turn), written out independently of the reader."""
    import copy
    old = copy.deepcopy(params)
    wrap = old["wrap_params"]
    wrap["theta"] = float(np.radians(wrap.pop("theta_deg")))
    wrap["stall_turn"] = float(np.radians(wrap.pop("stall_turn_deg")))
    return old


def test_a_collection_recorded_in_the_older_layout_reads_as_its_settings():
    from drake_continuum.experiments.collection import (
        collection_tree,
        in_stored_layout,
        run_params,
    )
    scenario = replace(load_config(), wrap=WrapParams(theta_deg=200.0, stall_turn_deg=7.5))
    now = run_params(scenario)
    stored = older_layout(now)
    assert stored["wrap_params"]["theta"] == np.radians(200.0)  # as the old loader made it
    assert in_stored_layout(now, stored) == stored  # equal to the bit: it resumes
    assert in_stored_layout(now, now) is now
    assert collection_tree(stored) == collection_tree(now)  # the degrees as given
    for deg in (7.5, 201.0, 0.1):
        old = older_layout(run_params(replace(scenario, wrap=WrapParams(theta_deg=deg))))
        assert collection_tree(old)["wrap"]["theta_deg"] == deg
    other = run_params(replace(scenario, wrap=WrapParams(theta_deg=201.0)))
    assert in_stored_layout(other, stored) != stored


def test_a_recorded_tree_of_an_unknown_layout_is_refused_by_name():
    tree = config_to_tree(load_config())
    tree["wrap"]["theta"] = float(np.radians(270.0))  # radians under the field's old name
    with pytest.raises(ConfigError, match=r"recorded settings: wrap.theta: unknown key "
                                          r"\(known: theta_deg, "):
        load_config(base=tree)
    del tree["wrap"]["theta"]
    tree["extra"] = {}
    with pytest.raises(ConfigError, match=r"recorded settings: unknown section extra \(known: "
                                          r"arm, planes, wrap, "):
        load_config(base=tree)


def test_a_tree_recorded_before_a_section_existed_reads_with_its_defaults(tmp_path):
    tree = config_to_tree(load_config(overrides=["chords.spacing=0.02"]))
    del tree["observed"]
    config = load_config(base=tree)
    assert config.observed == ObservedParams(frame="plane", tie_width=0.003)
    assert config.chords.spacing == 0.02
    # A file's section left out or left empty (every key commented out), the arm too: the
    # shipped settings, the shipped arm (not an arm.yaml that happens to lie beside it).
    (tmp_path / "arm.yaml").write_text("not: an arm\n")
    mine = tmp_path / "c.yaml"
    mine.write_text("observed:\n#  tie_width: 0.002\nwrap:\n  delta: 0.002\n")
    assert load_config(mine) == Config(wrap=WrapParams(delta=0.002))
    # --set reaches into a section or arm the file leaves out
    from drake_continuum.kinematics.arm import MODELS_DIR
    mine.write_text("wrap:\n  delta: 0.002\n")
    five = load_config(mine, overrides=[f"arm={MODELS_DIR / 'arm_5sections.yaml'}",
                                        "observed.tie_width=0.002", "active.horizon=3"])
    assert (five.arm().n_sections, five.observed.tie_width, five.active.horizon,
            five.wrap.delta) == (5, 0.002, 3, 0.002)


def test_a_config_names_its_arm_relative_to_itself_and_the_error_lists_the_paths_tried(
        tmp_path, monkeypatch):
    from drake_continuum.kinematics.arm import MODELS_DIR
    lab = tmp_path / "lab"
    (lab / "arms").mkdir(parents=True)
    four = (MODELS_DIR / "arm_5sections.yaml").read_text().replace("n_sections: 5",
                                                                   "n_sections: 4")
    (lab / "arms" / "mine.yaml").write_text(four)
    text = DEFAULT_CONFIG.read_text()
    (lab / "config.yaml").write_text(text.replace("arm: arm.yaml", "arm: arms/mine.yaml"))
    monkeypatch.chdir(tmp_path)  # not the config's folder
    assert load_config(lab / "config.yaml").arm().n_sections == 4
    # a copied config naming a shipped arm still finds it
    (lab / "copy.yaml").write_text(text.replace("arm: arm.yaml", "arm: arm_5sections.yaml"))
    assert load_config(lab / "copy.yaml").arm().n_sections == 5
    (lab / "lost.yaml").write_text(text.replace("arm: arm.yaml", "arm: gone.yaml"))
    with pytest.raises(ConfigError, match=rf"{lab / 'lost.yaml'}: arm: 'gone.yaml' not found "
                                          rf"\(tried {lab / 'gone.yaml'}, "
                                          rf"{MODELS_DIR / 'gone.yaml'}\)"):
        load_config(lab / "lost.yaml")
    # --set arm=PATH is a path from the working folder
    assert load_config(overrides=["arm=lab/arms/mine.yaml"]).arm().n_sections == 4
    with pytest.raises(ConfigError, match=rf"tried {tmp_path / 'mine.yaml'}"):
        load_config(lab / "config.yaml", overrides=["arm=mine.yaml"])


def test_libyaml_reads_and_writes_what_pyyaml_does():
    """parse_yaml (libyaml's parser where PyYAML has it) gives yaml.safe_load's tree for
    every shipped YAML file, and the text handed to yaml_load_typed is yaml.safe_dump's."""
    import yaml

    from drake_continuum import config
    from drake_continuum.files import parse_yaml

    for path in sorted(DEFAULT_CONFIG.parent.glob("*.yaml")):
        text = path.read_text()
        assert parse_yaml(text) == yaml.safe_load(text), path.name
    tree = config_to_tree(load_config())
    assert config._dump(tree) == yaml.safe_dump(tree)
    assert parse_yaml("a: [1.5, 2e-3, .inf, null, yes]") == yaml.safe_load(
        "a: [1.5, 2e-3, .inf, null, yes]")
