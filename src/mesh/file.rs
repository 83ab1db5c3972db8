//! Reading a mesh file of either format: the dispatch on its extension, apart from
//! [`super::import`] (which both readers use) so that no import circle forms.

use super::import::{ImportError, MeshFile};
use std::path::Path;

/// Read a mesh file by its extension: `.msh` (Gmsh MSH 4.1), `.inp` (Abaqus/CalculiX).
pub fn read(path: &Path) -> Result<MeshFile, ImportError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("msh") => super::gmsh::read(path),
        Some("inp") => super::abaqus::read(path),
        _ => Err(ImportError::UnknownFormat {
            file: path.to_path_buf(),
        }),
    }
}
