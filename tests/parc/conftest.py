"""Shared fixtures for the parc tests (the OpenGL context is the whole suite's: `tests/conftest.py`)."""
import pytest

#: Lines the raster tests add (how loose the segments are); printed at the end of the run.
LOOSENESS = []


@pytest.fixture
def looseness():
    """Append a line to the end-of-run looseness report."""
    return LOOSENESS.append


def pytest_terminal_summary(terminalreporter):
    if LOOSENESS:
        terminalreporter.section("parc raster: segment looseness (reported, not asserted)")
        for line in LOOSENESS:
            terminalreporter.write_line(line)
