"""Projection onto the linearised feasible set (reference §4): :func:`project` and its result
:class:`Projection`; :class:`SolverOptions`. One module per solver: ``exact`` (active-set NNLS),
``interior`` (Clarabel), ``proxqp`` (proxsuite); ``clusters`` splits the QP into independent
clusters and picks a solver for each."""
from sweep_core.numerics.projection.options import ROW_TOLERANCE, SolverOptions
from sweep_core.numerics.projection.project import Projection, first_cutoff, project

__all__ = ["ROW_TOLERANCE", "Projection", "SolverOptions", "first_cutoff", "project"]
