// L-shaped bracket: a foot [0, 1] x [0, 0.5] x [0, 0.2] resting on the foundation plane x3 = 0
// and an arm [0, 0.25] x [0, 0.5] x [0.2, 1] clamped at its top x3 = 1. Trilinear hexahedra
// (transfinite quadrangles in the (x1, x3) profile, extruded in x2 with recombined layers).
// Made with:  gmsh bracket.geo -3 -format msh22 -o bracket.msh
t = 0.25;   // arm thickness (x1)
h = 0.2;    // foot height (x3)
L = 1.0;    // foot length (x1)
Ht = 1.0;   // arm height (x3)
W = 0.5;    // width (x2)
Point(1) = {0, 0, 0};   Point(2) = {t, 0, 0};   Point(3) = {L, 0, 0};
Point(4) = {L, 0, h};   Point(5) = {t, 0, h};   Point(6) = {0, 0, h};
Point(7) = {t, 0, Ht};  Point(8) = {0, 0, Ht};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5};
Line(5) = {5, 6}; Line(6) = {6, 1}; Line(7) = {2, 5}; Line(8) = {5, 7};
Line(9) = {7, 8}; Line(10) = {8, 6};
Curve Loop(1) = {1, 7, 5, 6};  Plane Surface(1) = {1};   // corner block under the arm
Curve Loop(2) = {2, 3, 4, -7}; Plane Surface(2) = {2};   // rest of the foot
Curve Loop(3) = {-5, 8, 9, 10}; Plane Surface(3) = {3};  // arm
Transfinite Curve{1, 5, 9} = 5;
Transfinite Curve{2, 4} = 13;
Transfinite Curve{3, 7, 6} = 4;
Transfinite Curve{8, 10} = 11;
Transfinite Surface{1, 2, 3};
Recombine Surface{1, 2, 3};
ex1[] = Extrude {0, W, 0} { Surface{1}; Layers{8}; Recombine; };
ex2[] = Extrude {0, W, 0} { Surface{2}; Layers{8}; Recombine; };
ex3[] = Extrude {0, W, 0} { Surface{3}; Layers{8}; Recombine; };
Coherence;
eps = 1e-6;
Physical Surface("bottom") = Surface In BoundingBox{-eps, -eps, -eps, L + eps, W + eps, eps};
Physical Surface("arm_top") = Surface In BoundingBox{-eps, -eps, Ht - eps, t + eps, W + eps, Ht + eps};
Physical Surface("foot_top") = Surface In BoundingBox{t - eps, -eps, h - eps, L + eps, W + eps, h + eps};
Physical Surface("foot_end") = Surface In BoundingBox{L - eps, -eps, -eps, L + eps, W + eps, h + eps};
Physical Volume("bracket") = {ex1[1], ex2[1], ex3[1]};
