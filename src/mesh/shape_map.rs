//! Shape maps: design-dependent reference coordinates of imported (or any) nodes.
