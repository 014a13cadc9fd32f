"""Vocabularies are str-valued Enums whose values are the strings a configuration and stored
results hold; each is checked where its value is taken in."""

import pytest

from drake_continuum import config
from drake_continuum.errors import ConfigError
from drake_continuum.features.chords import (
    EDGES,
    FRAMES,
    ChordFrame,
    ChordHistogram,
    ChordParams,
    HistogramEdges,
)
from drake_continuum.kinematics.ik import IKMode, IKOptions
from drake_continuum.perception.bearing import BEARINGS, PlaneBearing
from drake_continuum.wrapping.planes import PlaneCentre
from drake_continuum.wrapping.wrap import WrapMethod
from drake_continuum.wrapping.wrap_types import STATUSES, WrapStatus

VOCABULARIES = [("wrap.ik.mode", IKMode), ("chords.frame", ChordFrame),
                ("classifier.edges", HistogramEdges), ("planes.bearing", PlaneBearing),
                ("planes.centre", PlaneCentre), ("wrap.method", WrapMethod)]


@pytest.mark.parametrize("key, vocabulary", VOCABULARIES)
def test_the_configuration_takes_every_value_of_a_vocabulary(key, vocabulary):
    section, *rest = key.split(".")
    for member in vocabulary:
        value = config.load_config(overrides=[f"{key}={member.value}"])
        for name in [section] + rest:
            value = getattr(value, name)
        assert value is member
    with pytest.raises(ConfigError, match=f"{key}: must be one of"):
        config.load_config(overrides=[f"{key}=no-such-value"])


def test_values_are_the_stored_strings():
    assert FRAMES == ("world", "wrap", "upright", "plane") and EDGES == ("uniform", "quantile")
    assert BEARINGS == ("world", "object")
    assert STATUSES[:2] == ("complete", "closed") and WrapStatus.NO_IK == "no_ik"
    assert [m.value for m in IKMode] == ["auto", "exact", "least_squares"]


def test_each_vocabulary_is_checked_where_it_is_taken_in():
    with pytest.raises(ConfigError, match="IKOptions.mode"):
        IKOptions(mode="newton")
    with pytest.raises(ConfigError, match="frame"):
        ChordParams(frame="tilted")
    with pytest.raises(ValueError, match="edges"):
        ChordHistogram(edges="random").fit([[[0.0, 1.0], [1.0, 2.0]]])
    assert IKOptions(mode=IKMode.EXACT).mode == "exact"
