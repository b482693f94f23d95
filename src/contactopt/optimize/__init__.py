"""Nonsmooth optimization: the bundle-trust method over a polyhedron."""

from .bundle import BTOptions, BundleResult, BundleState, minimize_bundle

__all__ = ["minimize_bundle", "BundleResult", "BundleState", "BTOptions"]
