"""The experiment configuration is the one source of the parameters' values."""

import numpy as np
import pytest

from drake_continuum.active import ActiveParams
from drake_continuum.chords import ChordParams
from drake_continuum.classify import ClassifierParams
from drake_continuum.config import load_config
from drake_continuum.wrap import WrapParams


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
    bad.write_text("arm: arm.yaml\n")
    with pytest.raises(ValueError, match=str(bad)):
        load_config(bad)
