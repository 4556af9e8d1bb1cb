"""The shipped applications the EKF's tests linearise."""

import pytest

from kfgen.hdl.ekf.models import ekf_models
from kfgen.hdl.engine.app import load_app


@pytest.fixture(scope="session")
def tracker():
    app = load_app("tracker:Tracker")
    return app, ekf_models(app)


@pytest.fixture(scope="session")
def nanosat():
    app = load_app("nanosat:Nanosat")
    return app, ekf_models(app)
