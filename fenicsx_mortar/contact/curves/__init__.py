"""Master curve geometry (docs/design.md §3, §6): the C0 polyline and the smoothed master
surfaces of the paper's Section 3.

A :class:`MasterCurve` maps (master segment i, ξ ∈ [0, 1]) to a point x(ξ) and its
ξ-derivatives. On segment i the curve depends on the coordinates of a fixed number L of
*curve points*, its *stencil*; all geometric methods take these local coordinates ``P`` as
a sequence of L points, each a 2-tuple of :class:`~.ad.Jet2` or of float arrays, so one
code path gives plain values (search, segmentation pre-pass, Newton iterations) and exact
derivatives (kernels).

Curve points and master nodes (``point_map``):
* local curves (polyline, averaged normals, Hermite): the points ARE the master nodes,
  ``point_map is None``;
* the global B-spline: the points are its control points, P = ``point_map`` @ X for both
  coordinate columns, X (n_nodes, 2) the master node coordinates; ``point_map`` is a
  scipy.sparse (n_points, n_nodes) matrix, constant for a frozen parametrization (see
  :class:`BSpline`).
``stencil``/``local_points`` index points, so the kernels' ``master_nodes`` index points;
the derivatives with respect to the nodes follow by the chain rule with ``point_map``
(∂q/∂X = point_mapᵀ ∂q/∂P, per coordinate).

Batch convention: ``seg_index`` is an integer array that broadcasts (numpy rules) against
the batch shape of ``P``/``xi``/``xs``: shape (k,) for a batch (k,) of segments, (1, k)
for the mortar Gauss batch (n_gauss, k) where ``P`` has batch (k,).

Implementations (:func:`make_curve` picks one by the scene's ``smoothing`` name):
* :class:`Polyline` — C0, today's behaviour ("none");
* :class:`AveragedNormals` — polyline with nodal averaged normals, eqs. 3.2–3.4;
* :class:`Hermite` — C1 cubic Hermite segments with averaged nodal tangents, eqs. 3.6–3.13;
* :class:`BSpline` — one global C2 cubic B-spline interpolating the nodes, eqs. 3.16–3.33.
Projection onto all of them: :mod:`.projection`.
"""
from .base import MasterCurve, make_curve
from .polyline import Polyline
from .averaged import AveragedNormals, AveragedSimple, AveragedTangent, AveragedWeighted
from .hermite import Hermite
from .bspline import BSpline, BSplineParametrization, span_basis

__all__ = ["MasterCurve", "make_curve", "Polyline", "AveragedNormals", "AveragedSimple",
           "AveragedTangent", "AveragedWeighted", "Hermite", "BSpline",
           "BSplineParametrization", "span_basis"]
