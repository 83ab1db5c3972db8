//! Imported meshes: a mesh file as it states itself, and how its bodies and sets enter a [`super::Mesh`].
//! (Stub with the agreed interface; the readers land from the `import` branch.)

use super::Mesh;
use crate::element::Shape;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A node of a mesh file.
#[derive(Clone, Debug, PartialEq)]
pub struct FileNode {
    /// Id in the file.
    pub id: u64,
    /// Coordinates.
    pub x: [f64; 3],
    /// Line in the file.
    pub line: usize,
}

/// A solid element of a mesh file.
#[derive(Clone, Debug, PartialEq)]
pub struct FileElement {
    /// Id in the file.
    pub id: u64,
    /// Shape.
    pub shape: Shape,
    /// Node ids.
    pub nodes: Vec<u64>,
    /// Line.
    pub line: usize,
}

/// A face of a face set.
#[derive(Clone, Debug, PartialEq)]
pub enum FileFace {
    /// By nodes.
    Nodes {
        /// Node ids.
        nodes: Vec<u64>,
        /// Line.
        line: usize,
    },
    /// By element side.
    Side {
        /// Element id.
        element: u64,
        /// Side 1..6.
        side: usize,
        /// Line.
        line: usize,
    },
}

/// A mesh as its file states it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshFile {
    /// Path.
    pub path: PathBuf,
    /// Nodes.
    pub nodes: Vec<FileNode>,
    /// Solid elements.
    pub elements: Vec<FileElement>,
    /// Element sets.
    pub element_sets: BTreeMap<String, Vec<usize>>,
    /// Node sets.
    pub node_sets: BTreeMap<String, Vec<u64>>,
    /// Face sets.
    pub face_sets: BTreeMap<String, Vec<FileFace>>,
}

/// A body added to a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportedBody {
    /// Group.
    pub group: usize,
    /// Mesh nodes.
    pub nodes: Vec<usize>,
    /// File id to mesh node.
    pub node_ids: BTreeMap<u64, usize>,
    /// File ids of the elements.
    pub element_ids: Vec<u64>,
}

/// Import errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// Not yet.
    #[error("{file}: mesh import is not built yet")]
    NotYet {
        /// File.
        file: PathBuf,
    },
}

/// Read a mesh file.
pub fn read(path: &Path) -> Result<MeshFile, ImportError> {
    Err(ImportError::NotYet {
        file: path.to_path_buf(),
    })
}

impl MeshFile {
    /// Add a body.
    pub fn add_to(
        &self,
        _mesh: &mut Mesh,
        _prefix: &str,
        _set: Option<&str>,
    ) -> Result<ImportedBody, ImportError> {
        Err(ImportError::NotYet {
            file: self.path.clone(),
        })
    }
}
