// wedge.geo: a wedge-shaped pad, 1.2 long (x1), 0.6 wide (x2), 0.4 high at x1 = 0 and 0.2 at x1 = 1.2,
// its underside on the foundation plane x3 = 0. Trilinear hexahedra: a structured quadrangle
// mesh of the (x1, x3) profile, extruded along x2 in layers.
// Mesh: gmsh wedge.geo -3 -format msh22 -o wedge.msh
L = 1.2;  W = 0.6;  H0 = 0.4;  H1 = 0.2;
Point(1) = {0, 0, 0};  Point(2) = {L, 0, 0};  Point(3) = {L, 0, H1};  Point(4) = {0, 0, H0};
Line(1) = {1, 2};  Line(2) = {2, 3};  Line(3) = {3, 4};  Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};  Plane Surface(1) = {1};
Transfinite Curve{1, 3} = 25;            // nodes along x1
Transfinite Curve{2, 4} = 7;             // nodes along x3
Transfinite Surface{1};  Recombine Surface{1};
v[] = Extrude {0, W, 0} { Surface{1}; Layers{12}; Recombine; };
// v[0]: the copy of surface 1 at x2 = W, v[1]: the volume, v[2] … v[5]: the faces swept by
// curves 1 … 4. The named parts contactopt refers to ([body] clamped, contact; a load's "on"):
Physical Surface("contact") = {v[2]};    // underside, on x3 = 0: the designed contact face
Physical Surface("end") = {v[3]};        // thin end, x1 = L
Physical Surface("top") = {v[4]};        // sloped top
Physical Surface("clamped") = {v[5]};    // thick end, x1 = 0
Physical Volume("wedge") = {v[1]};
