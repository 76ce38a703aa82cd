"""eqparse.gauge: which equations are odd in their state (y -> -y maps solutions to solutions)."""
from __future__ import annotations

import pytest

from fitode.eqparse import parse
from fitode.eqparse.gauge import _odd


@pytest.mark.parametrize("eq, odd", [
    ("theta'' = -g/L*sin(theta) - zeta*theta'", True),
    ("x'' = -k*x**3", True),
    ("x'' = -a*x*abs(x)", True),
    ("x'' = -a*tan(x) - b*sinh(x')", True),
    # odd only once sin^2 + cos^2 = 1 is used: the value at a point cannot settle it, simplify must
    ("x'' = k*(sin(x)**2 + cos(x)**2 - 1)*x + a*x", True),
    ("x'' = 1e10*(sin(x)**2 + cos(x)**2 - 1) - a*x", True),
    ("y'' = -g", False),
    ("x'' = -a*abs(x)", False),
    ("h' = -k*sqrt(h)", False),
    ("x' = -a*exp(x)", False),
    ("x'' = g*(sin(alpha) - mu*cos(alpha))", False),
    ("u' = a*u - b*u*v; v' = -c*v + d*u*v", False),
])
def test_odd_equations_are_told_from_the_others(eq, odd):
    assert _odd(parse(eq)) is odd
