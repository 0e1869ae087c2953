"""Shared by every test package: the OpenGL context (fixtures `gl_context`, `gl`; it lives here and
nowhere else), `--soak`, more random scenes than the suite runs, and the end-of-run report of how
loose the raster's segments are (fixture `looseness`).

The random-scene tests (`parc` against `brute`) take their scene from a
seed, and the hard-ray categories their rays. The suite runs a fixed set of
seeds, enough to cover every kind of volume, view and supercell; ``--soak N``
adds ``N`` more seeds to each such test, from ``--soak-start`` on, for a
longer check before a release or after a change to the raster, the walk or
the cubic::

    ./dev.sh test tests/parc -k equals_brute --soak 2000
    ./dev.sh test tests/raycast -k hard_category --soak 10

A failure names its seed in the test id, so that scene runs alone again with::

    ./dev.sh test "tests/parc/test_parc_equals_brute.py::test_parc_equals_brute[1000123]" \
        --soak 1 --soak-start 1000123
"""
import argparse

import pytest

#: The first seed `--soak` adds: past every seed the suite runs by itself.
SOAK_START = 1_000_000


def _count(text):
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {n}")
    return n


def pytest_addoption(parser):
    group = parser.getgroup("parc", "random scenes")
    group.addoption("--soak", type=_count, default=0, metavar="N",
                    help="run N more random scenes in each random-scene test (parc against brute), "
                         "seeds from --soak-start on")
    group.addoption("--soak-start", type=_count, default=SOAK_START, metavar="SEED",
                    help=f"the first extra seed --soak runs (default {SOAK_START:,})")


def pytest_configure(config):
    config.addinivalue_line("markers", "random_scenes(n): parametrize the test's `seed` with seeds 0 .. n-1, "
                                       "and the extra seeds --soak asks for")


def pytest_generate_tests(metafunc):
    marker = metafunc.definition.get_closest_marker("random_scenes")
    if marker is None:
        return
    extra = metafunc.config.getoption("soak")
    start = metafunc.config.getoption("soak_start")
    metafunc.parametrize("seed", [*range(marker.args[0]), *range(start, start + extra)])


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
    from parc.gl import get_context
    # Current again (a render lets it go as it ends): with none, reading the error reads nothing.
    _ = get_context().error  # reading clears any stale error from an earlier failure
    yield gl_context
    assert get_context().error == "GL_NO_ERROR"


#: Lines the raster tests add (how loose the segments are); printed at the end of the run.
LOOSENESS = []


@pytest.fixture
def looseness():
    """Append a line to the end-of-run looseness report."""
    return LOOSENESS.append


def pytest_sessionfinish(session):
    # In a pytest-xdist worker: hand the lines to the controller, which prints the report.
    output = getattr(session.config, "workeroutput", None)
    if output is not None:
        output["looseness"] = list(LOOSENESS)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    LOOSENESS.extend(getattr(node, "workeroutput", {}).get("looseness", []))


def pytest_terminal_summary(terminalreporter):
    if LOOSENESS:
        terminalreporter.section("parc raster: segment looseness (bounded in test_raster.py)")
        for line in LOOSENESS:
            terminalreporter.write_line(line)
