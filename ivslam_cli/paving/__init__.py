"""Subpavings on a regular grid (SIVIA), and set operations on them.

    >>> from ivslam_cli import paving
    >>> sector = paving.polar_set((0.0, 0.0), rho=(4.9, 5.1), theta=(0.3, 0.32))
    >>> p = paving.pave(sector, [[-10, 10], [-10, 10]], eps=0.01)
    >>> p.inner_area() <= 0.02 <= p.outer_area()
    True

A boundary cell may hold several boxes (``parts``, stored flat with per-cell offsets
``start``): ``sub=s`` cuts each boundary cell into a ``2^s x 2^s`` sub-grid and keeps the
contracted pieces, so the outer area goes below the one-box-per-cell limit (the cells' hulls,
``box_area()``); the inner approximation stays the union of the INNER cells:

    >>> q = paving.pave(sector, [[-10, 10], [-10, 10]], eps=0.01, sub=2)
    >>> q.inner_area() <= 0.02 <= q.outer_area() < q.box_area() <= p.outer_area()
    True

``refine=d`` refines the boundary cells as a separator paving does (outer contraction and the
complementary one, boundary boxes bisected down to ``eps / 2^d``); the boxes proven inside
within boundary cells are kept as ``inner_parts`` and counted in the inner area:

    >>> r = paving.pave(sector, [[-10, 10], [-10, 10]], eps=0.01, refine=2)
    >>> p.inner_area() < r.inner_area() <= 0.02 <= r.outer_area() < p.outer_area()
    True
"""

from ivslam_cli.paving.classifiers import Intersection, KernelClassifier, box_set, polar_set
from ivslam_cli.paving.grid import BOUNDARY, INNER, Grid, GridPaving, PavingLimitError, empty_paving
from ivslam_cli.paving.ops import (
    affine,
    contains_points,
    from_boxes,
    intersection,
    minkowski_sub,
    negate,
    translate,
    union,
)
from ivslam_cli.paving.sivia import pave

__all__ = [
    "BOUNDARY", "INNER", "Grid", "GridPaving", "Intersection", "KernelClassifier",
    "PavingLimitError", "affine", "box_set", "contains_points", "empty_paving", "from_boxes",
    "intersection", "minkowski_sub", "negate", "pave", "polar_set", "translate", "union",
]
