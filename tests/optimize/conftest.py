"""Fixtures of the rendered-search tests."""

import pytest

from pacam_render.lightfield import StoreSpec, render_lightfield
from tests.optimize.small_store import SPEC


@pytest.fixture(scope="session")
def store(tmp_path_factory):
    """:data:`SPEC`'s light-field store (uniform proposal), rendered once for the session."""
    folder = tmp_path_factory.mktemp("lf") / "store"
    return render_lightfield(StoreSpec(SPEC, alpha=1.0), folder, progress=False)
