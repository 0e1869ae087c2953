"""The GLSL sources, read as text: what one driver accepts and another refuses."""
import re

import numpy as np
import pytest

from parc.gl import SHADER_DIR

SOURCES = sorted(SHADER_DIR.iterdir())

# A floating constant: digits with a point or an exponent, and its suffix.
LITERAL = re.compile(r"(?<![\w.])((?:\d+\.\d*|\.\d+|\d+(?=[eE]))(?:[eE][-+]?\d+)?)(lf|LF|f|F)?(?![\w.])")


def code_only(text):
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", " ", text)


def test_literal_pattern():
    found = LITERAL.findall("x = 1e300 + 2.5lf * .5 - 3 + 4.f + 1e-6LF; v2 = vec2(0.); y[2] = 7;")
    assert found == [("1e300", ""), ("2.5", "lf"), (".5", ""), ("4.", "f"), ("1e-6", "LF"), ("0.", "")]


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.name)
def test_unsuffixed_constants_are_exact_in_float32(path):
    # GLSL reads a constant without "lf" as a float, whatever it is assigned
    # to: NVIDIA's compiler refuses dvec2(1e300) ("floating point constant
    # overflow") where Mesa quietly makes it inf, and 1e-100 or 0.999 lose
    # their value in a double expression. A constant that float32 holds
    # exactly means the same on every driver.
    inexact = [text for text, suffix in LITERAL.findall(code_only(path.read_text()))
               if not suffix and float(np.float32(text)) != float(text)]
    assert inexact == [], f"{path.name}: write these as double constants (suffix lf): {inexact}"
