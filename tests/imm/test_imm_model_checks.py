"""A wrong-shaped matrix of an :class:`~kfgen.sim.imm.reference.ImmModel` is named in the error,
whichever it is (issue 34: a wrong-shaped F once blamed H)."""

import numpy as np
import pytest

from kfgen.sim.imm.reference import ImmModel

#: A model of n = 4 states and d = 2 measurements.
GOOD = dict(name="cv", F=np.eye(4), Q=np.eye(4), H=np.ones((2, 4)), R=np.eye(2))


@pytest.mark.parametrize("wrong, match", [
    (dict(F=np.eye(3)), r"F must be a 4 x 4 matrix, not of shape \(3, 3\)"),
    (dict(F=np.ones((4, 3))), r"F must be square, not of shape \(4, 3\)"),
    (dict(Q=np.eye(5)), r"Q must be a 4 x 4 matrix, not of shape \(5, 5\)"),
    (dict(Q=np.ones((4, 5))), r"Q must be square, not of shape \(4, 5\)"),
    (dict(H=np.ones((2, 3))), r"H must have n = 4 columns, not of shape \(2, 3\)"),
    (dict(R=np.eye(3)), r"R must be a 2 x 2 matrix, not of shape \(3, 3\)"),
    (dict(F=np.eye(3), Q=np.eye(5)), r"F, Q and H must agree on the state size n .*F \(3, 3\), Q \(5, 5\), "
                                     r"H \(2, 4\)"),
])
def test_each_matrix_names_its_own_shape_error(wrong, match):
    with pytest.raises(ValueError, match=rf"model 'cv': {match}"):
        ImmModel(**{**GOOD, **wrong})


def test_a_model_that_fits():
    m = ImmModel(**GOOD)
    assert (m.n, m.d) == (4, 2)
