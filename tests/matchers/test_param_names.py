"""One name per meaning: renamed parameters keep their old names as aliases (formats.md), without a warning."""

from __future__ import annotations

import dataclasses

import pytest

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.matchers.event_area.params import EventAreaParams
from cvstereo.matchers.event_vector.params import EventVectorParams
from cvstereo.matchers.frame.params import FrameClusterParams
from cvstereo.matchers.frame_area.params import FrameAreaParams
from cvstereo.matchers.opencv.params import StereoBMParams, StereoSGBMParams
from cvstereo.matchers.registry import create_matcher, matcher_class, params_from_meta, parse_param_strings

#: (method, old name, old value, new name, new value)
RENAMES = [
    ("frame", "sigma", 1.5, "kernel_sigma", 1.5),
    ("frame-area", "sigma", 0.8, "kernel_sigma", 0.8),
    ("event-area", "max_sad", 500.0, "max_cost", 500.0),
    ("stereobm", "num_disparities", 48, "max_disparity", 47),
    ("sgbm", "num_disparities", 32, "max_disparity", 31),
]


@pytest.mark.parametrize(("method", "old", "old_value", "new", "new_value"), RENAMES)
def test_old_names_are_accepted_everywhere(method, old, old_value, new, new_value):
    cls = matcher_class(method)
    expected = cls.make_params(**{new: new_value})
    assert getattr(expected, new) == new_value and getattr(cls.Params(), new) != new_value
    assert cls.Params(**{old: old_value}) == cls.Params(**{new: new_value})  # Python keyword
    assert create_matcher(method, param_set="thesis", **{old: old_value}).params == expected  # through the registry
    assert create_matcher(method, **{old: old_value}).params == create_matcher(method, **{new: new_value}).params
    assert cls.make_params(**parse_param_strings(cls.Params, [f"{old}={old_value}"])) == expected  # --param
    assert params_from_meta({"method": method, "params": {old: old_value}}) == expected  # stored meta
    described = create_matcher(method, **{old: old_value}).describe()["params"]
    assert old not in described and described[new] == new_value  # written under the new name
    with pytest.raises(ValueError, match=f"give '{new}' or its old name '{old}', not both"):
        cls.Params(**{old: old_value, new: new_value})


def test_converted_alias_uses_the_min_disparity_given():
    assert StereoBMParams(num_disparities=64, min_disparity=16).max_disparity == 79
    assert StereoBMParams(num_disparities=64).num_disparities == 64 == StereoBMParams().num_disparities
    with pytest.raises(ValueError, match="multiple of 16"):
        StereoSGBMParams(max_disparity=40)


def test_one_name_and_type_per_meaning():
    """Fields that mean the same have the same name and type in every parameter class that has them."""
    types: dict[str, set] = {}
    for cls in (FrameClusterParams, FrameAreaParams, EventAreaParams, EventVectorParams, StereoBMParams,
                StereoSGBMParams, DynamicFrameParams):
        for f in dataclasses.fields(cls):
            types.setdefault(f.name, set()).add(f.type)
    for name in ("kernel_sigma", "kernel_size", "max_disparity", "max_cost", "threshold", "polarity"):
        assert len(types[name]) == 1, (name, types[name])
    for old in ("sigma", "max_sad", "num_disparities"):
        assert old not in types
