"""Shared fixtures for the parc tests: the OpenGL context lives here and nowhere else."""
import pytest

#: Lines the raster tests add (how loose the segments are); printed at the end of the run.
LOOSENESS = []


@pytest.fixture(scope="session")
def gl_context():
    """The process-wide headless context, or a skip with the reason."""
    from parc.gl import OpenGLUnavailable, get_context
    try:
        return get_context()
    except OpenGLUnavailable as exc:
        pytest.skip(f"OpenGL tests need a headless EGL context: {exc}")


@pytest.fixture
def gl(gl_context):
    """The context for one test; the test must leave no GL error behind."""
    _ = gl_context.error  # reading clears any stale error from an earlier failure
    yield gl_context
    assert gl_context.error == "GL_NO_ERROR"


@pytest.fixture
def looseness():
    """Append a line to the end-of-run looseness report."""
    return LOOSENESS.append


def pytest_terminal_summary(terminalreporter):
    if LOOSENESS:
        terminalreporter.section("parc raster: segment looseness (reported, not asserted)")
        for line in LOOSENESS:
            terminalreporter.write_line(line)
