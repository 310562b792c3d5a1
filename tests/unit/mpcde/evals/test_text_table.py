"""The tables' cell formatting: missing values as a right-aligned dash of the spec's width."""

from __future__ import annotations

import math

import pytest

from mpcde.evals.text_table import cell


@pytest.mark.parametrize("spec, width", [("7.3f", 7), ("+.0f", 0), ("+6.1f", 6), ("-5d", 5), (" 4.1f", 4), (">8.2f", 8), ("*^10", 10), ("08.1f", 8), ("d", 0)])
def test_a_missing_value_is_a_dash_of_the_spec_s_width_even_with_a_sign_option(spec, width):
    for missing in (None, math.nan):
        assert cell(missing, spec) == "-".rjust(width)


def test_a_value_is_formatted_with_the_spec():
    assert cell(3.14159, "+.1f") == "+3.1"
    assert cell(-2.0, "7.3f") == " -2.000"
