// Round pad: a cylinder of radius 0.5 and height 0.25 standing on the foundation plane x3 = 0,
// its top disc clamped to the structure above it. Linear tetrahedra.
// Made with:  gmsh round_pad.geo -3 -format msh41 -o round_pad.msh
SetFactory("OpenCASCADE");
R = 0.5;
H = 0.25;
Cylinder(1) = {0.5, 0.5, 0, 0, 0, H, R};
eps = 1e-6;
bottom() = Surface In BoundingBox{-1, -1, -eps, 2, 2, eps};
top() = Surface In BoundingBox{-1, -1, H - eps, 2, 2, H + eps};
all() = Surface{:};
side() = all();
side() -= bottom();
side() -= top();
Physical Surface("bottom") = {bottom()};
Physical Surface("top") = {top()};
Physical Surface("side") = {side()};
Physical Volume("pad") = {1};
Mesh.MeshSizeMax = 0.055;
Mesh.MeshSizeMin = 0.02;
Mesh.ElementOrder = 1;
Mesh.Optimize = 1;
