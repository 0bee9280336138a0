"""Shared fixtures. Rendering tests use small grids of the real Mitsuba scenes."""

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    """Keep generated meshes out of the user's cache."""
    os.environ.setdefault("SPARSELT_CACHE", str(tmp_path_factory.mktemp("cache")))


@pytest.fixture(scope="session")
def cornell():
    from sparselt.rendering.scenes import get_scene

    return get_scene("cornell-box")

