import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.model import align_inputs


def test_function_model_batch_and_nan_rows():
    m = rq.FunctionModel(lambda x: np.log(x[:, 0]), ["x"], ["y"])
    out = rq.evaluate(m, np.array([[1.0], [-1.0], [np.e]]))
    np.testing.assert_allclose(out.values[[0, 2], 0], [0.0, 1.0])
    assert list(out.failures) == [1]
    assert out.ok.tolist() == [True, False, True]


def test_wrong_shape_is_reported():
    m = rq.FunctionModel(lambda x: np.zeros((x.shape[0], 3)), ["x"], ["y"])
    with pytest.raises(ModelShapeError, match=r"expected \(2, 1\)"):
        rq.evaluate(m, np.zeros((2, 1)))


def test_align_inputs():
    m = rq.FunctionModel(lambda x: x, ["a", "b"], ["a", "b"])
    assert align_inputs(m, ["a", "b"]) is None
    assert align_inputs(m, ["b", "a"]).tolist() == [1, 0]
    with pytest.raises(ParameterError, match="not inputs of the model"):
        align_inputs(m, ["a", "c"])
