"""Declared parameter constraints: one validator, read at construction, in --param and in a sweep's grid."""

from __future__ import annotations

import dataclasses
import inspect
import math

import pytest

from cvstereo.frames.dynamic import DynamicFrameParams
from cvstereo.matchers.constraints import Constraint, check_value, validate
from cvstereo.matchers.event_time.params import EventTimeParams
from cvstereo.matchers.frame.params import FrameClusterParams
from cvstereo.matchers.fused.params import FusedParams
from cvstereo.matchers.opencv.params import StereoBMParams
from cvstereo.matchers.registry import METHODS, check_param_item, matcher_class, parse_param_strings
from cvstereo.matchers.sets import ADAPTIVE, AdaptiveDefaults, resolve


@pytest.mark.parametrize(("cls", "field", "good", "bad"), [
    # (0, 1]: the edge 1 is allowed, 0 is not.
    (DynamicFrameParams, "decay", [1.0, 1e-9], [0.0, 1.0000001]),
    # -1 switches the occlusion test off; otherwise [0, 16] px.
    (FusedParams, "occlusion_margin", [-1.0, 0.0, 16.0], [-0.5, -2.0, 16.5]),
    (FusedParams, "sgm_paths", [0, 2, 4], [1, 3, 8]),
    (FusedParams, "border_rows", [-1, 16], [-2, 17]),
    # StereoBM narrows the odd side to 5..255.
    (StereoBMParams, "block_size", [5, 255], [3, 7 - 1, 257]),
    (EventTimeParams, "kernel_size", [1, 3, 9], [0, 2, -1]),
])
def test_a_declaration_allows_its_edges_and_refuses_beyond(cls, field, good, bad):
    for value in good:
        assert getattr(cls(**{field: value}), field) == value
        assert check_param_item(cls, field, value) == value
    for value in bad:
        with pytest.raises(ValueError, match=rf"{cls.__name__}: parameter '{field}' must be"):
            cls(**{field: value})
        with pytest.raises(ValueError, match=rf"grid '{field}' must be"):
            check_param_item(cls, field, value, where="grid")


def test_construction_param_strings_and_the_grid_say_the_same_rule():
    rule = "must be one of 0, 2, 4, got 3."
    with pytest.raises(ValueError) as built:
        FusedParams(sgm_paths=3)
    with pytest.raises(ValueError) as parsed:
        parse_param_strings(FusedParams, ["sgm_paths=3"])
    with pytest.raises(ValueError) as item:
        check_param_item(FusedParams, "sgm_paths", 3)
    assert str(built.value) == f"FusedParams: parameter 'sgm_paths' {rule}"
    assert str(parsed.value) == f"--param 'sgm_paths' {rule}"
    assert str(item.value) == f"parameter 'sgm_paths' {rule}"


def test_every_way_of_building_validates():
    with pytest.raises(ValueError, match="'threshold' must be > 0"):
        dataclasses.replace(FrameClusterParams(), threshold=0.0)
    with pytest.raises(ValueError, match=r"FrameClusterParams: parameter 'window_us' must be an integer, got nan"):
        FrameClusterParams(window_us=math.nan)
    # A whole float (JSON, YAML) becomes the int it stands for, at construction too.
    got = FrameClusterParams(window_us=40000.0).window_us
    assert got == 40000 and type(got) is int


def test_a_rule_between_fields_is_a_named_method():
    with pytest.raises(ValueError, match=r"need 0 <= p1 <= p2 .* got p1=5.0, p2=4.0"):
        FusedParams(p1=5.0, p2=4.0)
    assert FusedParams(p1=4.0, p2=4.0).p2 == 4.0


def test_constraint_words():
    assert Constraint(gt=0, le=1).describe(integer=False) == "in (0, 1]"
    assert Constraint(ge=1, le=9).describe(integer=True) == "a whole number in 1..9"
    assert Constraint(ge=0, le=16, off=-1, note="px").describe(integer=False) == "-1 (off) or in [0, 16] (px)"
    assert Constraint(gt=0).describe(integer=False) == "> 0"
    assert Constraint(choices=(0, 2, 4)).describe(integer=True) == "one of 0, 2, 4"


def test_no_params_class_checks_by_hand_what_it_declares():
    # The checks are declarations: no __post_init__ in any built-in parameter class or its bases.
    for method in METHODS:
        for klass in matcher_class(method).Params.__mro__:
            if klass.__module__.startswith("cvstereo."):
                assert "__post_init__" not in vars(klass), f"{klass.__name__} ({method})"


def test_a_plugin_class_without_declarations_gets_the_type_rules():
    @dataclasses.dataclass(frozen=True)
    class Plain:
        threshold: float = 1.0
        window_us: int = 10

    with pytest.raises(ValueError, match=r"Plain: parameter 'threshold' must be a finite number, got nan"):
        validate(Plain(threshold=math.nan))
    assert check_value(Plain, "window_us", 20.0) == 20


def test_each_params_class_carries_its_adaptive_set():
    # docs/algorithms.md: the frame matcher keeps a match only with 3 agreeing neighbours under adaptive, and
    # dv-semidense and fused run the same under both sets.
    spec = matcher_class("frame").Params.adaptive
    assert isinstance(spec, AdaptiveDefaults) and spec.variant == "separate" and spec.params["min_support"] == 3
    assert resolve("frame", None, "adaptive") == ("separate", spec.params)
    assert resolve("frame", None, "thesis") == (None, {})
    assert {"dv-semidense", "fused"}.isdisjoint(ADAPTIVE)
    assert list(ADAPTIVE) == ["frame", "frame-area", "event-time", "event-area", "event-vector", "stereobm", "sgbm"]
    assert ADAPTIVE["sgbm"].params == {"border_horizon_us": 40_000, "border_rows": 16}


def test_params_modules_hold_one_class_per_matcher():
    # Each method's class is defined in its own package's params module.
    for method in METHODS:
        cls = matcher_class(method)
        package = cls.__module__.rsplit(".", 1)[0]
        assert inspect.getmodule(cls.Params).__name__ == f"{package}.params", method
