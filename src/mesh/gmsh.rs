//! Gmsh MSH 4.1 meshes, ASCII and binary: reader and writer (see [`super::import`]).
