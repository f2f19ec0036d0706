"""Which gtsam.Values fusionkit's own evaluator is costing or linearizing right now (docs/plugin_guide.md#factors-
with-many-variables).

GTSAM calls each CustomFactor on its own; a plugin whose factors share an expensive evaluation (every marker
factor of an arm entry: one vectorized forward kinematics) would read all its variables in every callback to be
sure its cached results are still at them. During one pass of fusionkit's GraphEvaluator (linearize, error,
per-record errors and residuals) every callback receives the same Values object, unchanged for the whole pass:
`pass_token(values)` returns a token unique to that pass when `values` is that object, so the first callback may
evaluate every factor at once and the others read their rows without reading a variable. Any other caller
(GTSAM's own optimizers, gtsam.Marginals, iSAM2) gets None: the plugin checks its variables as before.
"""

from __future__ import annotations

from contextlib import contextmanager

import gtsam

_current: tuple[gtsam.Values, object] | None = None


@contextmanager
def evaluation_pass(values: gtsam.Values):
    """Mark the callbacks made inside as one pass over `values` (passes nest: the inner one counts)."""
    global _current
    outer, _current = _current, (values, object())
    try:
        yield
    finally:
        _current = outer


def pass_token(values: gtsam.Values) -> object | None:
    """A token unique to fusionkit's current evaluation pass when `values` is the very Values object it evaluates
    (then unchanged until the pass ends); None otherwise."""
    current = _current
    return current[1] if current is not None and current[0] is values else None
