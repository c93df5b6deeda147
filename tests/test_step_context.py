"""A step builds each of its models once (issue 25): :meth:`StepContext.model` gives the same
model for the same fixed inputs, a new one for other values."""

from __future__ import annotations

import numpy as np

import rotoruq as rq
from rotoruq.steps import StepContext


def test_a_step_builds_each_model_once():
    built = []

    def make_model(inputs, responses, fixed):
        built.append(dict(fixed))
        return rq.FunctionModel(lambda x, k=fixed["k"]: k * x[:, :1], list(inputs),
                                list(responses))

    ctx = StepContext("s", "sampling", {}, rq.ParameterSpace({"a": rq.Normal(0.0, 1.0)}),
                      ("y",), {"k": 1.0, "h": 4.0}, make_model, np.random.default_rng(0))
    first = ctx.model()
    assert ctx.model() is first and ctx.model({"k": 1.0}) is first
    other = ctx.model({"k": 2.0})
    assert other is not first and ctx.model({"k": 2.0, "h": 4.0}) is other
    assert built == [{"k": 1.0, "h": 4.0}, {"k": 2.0, "h": 4.0}]
    np.testing.assert_array_equal(rq.evaluate(other, [[3.0]]).values, [[6.0]])
