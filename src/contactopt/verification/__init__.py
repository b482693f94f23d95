"""Independent checks of contactopt: set-ups whose answer is known without contactopt.

- ``brick``: Q1 elasticity on a clamped box, assembled apart from ``contactopt.fem``, for
  checking the factorizations and the condensation on matrices contactopt did not make;
- ``hertz``: a rigid sphere, cylinder and flat punch pressed into a block through
  ``[obstacle]``, measured against Hertz, Mindlin and Boussinesq;
- ``hertz_tets``: the rigid sphere pressed into a quarter block of Gmsh tetrahedra (linear and
  quadratic) or of a graded grid split into tetrahedra, its pressure against Hertz's;
- ``hertz_stress``: a paraboloid pressed onto the rigid plane, its peak von Mises stress
  against Hertz's subsurface field;
- ``spence``: the rigid flat punch and the rigid paraboloid pressed with friction, from the
  half-space's axisymmetric integral equations: the stick ratio c/a of the monotonic frictional
  Hertz indentation, and that indentation solved step by step (its pressure against Hertz's).

The tests run them on coarse meshes; the scripts in ``benchmarks/`` refine them and print the
tables of docs/obstacles.md and docs/objectives.md.
"""
