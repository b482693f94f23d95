"""Nonsmooth optimization: the bundle-trust method over a polyhedron, and nonsmooth constraints
by an exact penalty; :func:`minimize` chooses between them by ``method``. Test problems of the
nonsmooth literature: :mod:`contactopt.optimize.gallery`."""

from ._minimize import METHODS, minimize
from .bundle import BTOptions, BundleResult, BundleState, minimize_bundle

__all__ = ["minimize", "METHODS", "minimize_bundle", "BundleResult", "BundleState", "BTOptions"]
