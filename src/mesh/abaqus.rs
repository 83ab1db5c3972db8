//! Abaqus/CalculiX `.inp` meshes: reader and writer (see [`super::import`]).
