//! Imported meshes: a mesh file as it states itself, and how its bodies and sets enter a [`super::Mesh`].
