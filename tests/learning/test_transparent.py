"""The classifier's blocks and what they need: a transparent object's model leaves out the
camera's view of the object and classifies from touch alone."""

import numpy as np
import pytest

from drake_continuum.config import Config
from drake_continuum.errors import InputError
from drake_continuum.learning.model import classify_wraps, train
from drake_continuum.learning.pipeline import BLOCKS, ClassifierParams
from drake_continuum.learning.records import object_record
from synthetic_wraps import separable_objects


@pytest.fixture(scope="module")
def records():
    # Views that tell the classes apart too: circles 3 cm tall, squares 8 cm.
    return [object_record(oid, cat, wraps, view=[0.03 if cat == "circle" else 0.08, 0.1, 0.1])
            for oid, cat, wraps in separable_objects(4, 3)]


def test_the_recommended_model_names_the_block_that_needs_the_object_visible(records):
    model = train(records)
    assert model.uses_view and model.needs_object_visible == ("view",)
    assert set(model.blocks) == set(BLOCKS)


def test_the_touch_only_model_has_no_view_block_and_needs_no_view(records):
    params = ClassifierParams().touch_only()
    assert params.view_weight == 0 and params.extent_weight == ClassifierParams().extent_weight
    model = train(records, scenario=Config(classifier=params))
    assert not model.uses_view and model.needs_object_visible == ()
    assert "view" not in model.blocks and {"histogram", "wrap", "extent"} <= set(model.blocks)
    oid, cat, wraps = separable_objects(1, 3, seed=5)[1]
    assert classify_wraps(model, wraps, view=None)[0] == cat == "square"
    with pytest.raises(InputError, match="view"):
        classify_wraps(train(records), wraps, view=None)
    assert np.isfinite(classify_wraps(model, wraps)[1]).all()
