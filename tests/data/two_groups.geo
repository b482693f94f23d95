// A small box of linear tetrahedra whose bottom face belongs to two physical groups
// ("bottom" and "base"), written as a Gmsh 4.1 file for the reader tests.
// Made with:  gmsh two_groups.geo -3 -format msh41 -o two_groups.msh
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 0.5, 0.4};
eps = 1e-6;
bot() = Surface In BoundingBox{-eps, -eps, -eps, 1 + eps, 0.5 + eps, eps};
top() = Surface In BoundingBox{-eps, -eps, 0.4 - eps, 1 + eps, 0.5 + eps, 0.4 + eps};
Physical Surface("bottom") = {bot()};
Physical Surface("base") = {bot()};
Physical Surface("top") = {top()};
Physical Volume("solid") = {1};
Mesh.MeshSizeMax = 0.2;
