//! Imported meshes: a mesh file as it states itself ([`MeshFile`], read by [`super::read`]: [`super::gmsh`]
//! and [`super::abaqus`]), and how one of its bodies and its sets enter a [`super::Mesh`]
//! ([`MeshFile::add_to`]).
//!
//! ```no_run
//! use fricsens::mesh::{import, Mesh};
//! use std::path::Path;
//!
//! let file = fricsens::mesh::read(Path::new("bracket.msh"))?; // or .inp
//! let mut mesh = Mesh::default();
//! // the hexahedra of physical volume "bracket", its sets as "bracket.NAME"
//! let body = file.add_to(&mut mesh, "bracket", Some("bracket"))?;
//! let contact_faces = &mesh.face_sets["bracket.bottom"];
//! # let _ = (body, contact_faces);
//! # Ok::<(), import::ImportError>(())
//! ```
//!
//! # Rules
//!
//! * **Which elements.** `add_to(mesh, prefix, Some(set))` takes the solid elements of element
//!   set `set`; with `None`, every solid element of the file. A Gmsh file without physical
//!   groups has no sets at all (none is invented): import it with `None`.
//! * **Nodes.** The body's nodes enter the mesh in the order they first appear in the body's
//!   elements (element after element, each in its node order), so the numbering is
//!   deterministic and independent of the file's node order.
//! * **Set names.** Every set of the file with at least one node (face) on the body becomes
//!   `"{prefix}.{name}"`, restricted to the body. `{prefix}.all` holds the body's nodes and
//!   `{prefix}.boundary` its boundary faces (and their nodes). A face set yields a node set of
//!   the same name (its nodes) when the file has no node set of that name; so does an element
//!   set (its elements' nodes). A file set called `all` or `boundary` is accepted only when it
//!   equals the generated one on the body (Abaqus files often carry `NSET=ALL`).
//!   Abaqus names are case-insensitive: the reader keeps the file's first spelling, and
//!   `add_to` matches the element set name case-insensitively for Abaqus files (exactly for
//!   Gmsh files, whose names are case-sensitive).
//! * **Faces.** A file face (given by its nodes, or as side `Sn` of an element) is matched to
//!   an element face by its sorted node ids, never by the file's node order, and enters the
//!   mesh oriented outward as [`Shape::faces`] orders it. A face of no element of the file is
//!   an error; a face two body elements share (interior) is an error; a face of another body's
//!   elements is skipped. A face listed twice in one set enters once.
//! * **Unused nodes.** Gmsh never writes a node that no saved element uses (checked with Gmsh
//!   4.15: with physical groups on one surface only, only that surface's nodes are written), so
//!   in a Gmsh file an unused node is an error. Abaqus files legitimately hold nodes no element
//!   uses (reference points of rigid bodies and couplings): there an unused node is an error
//!   only when it belongs to a node set that also holds nodes of the imported body (the body's
//!   copy of the set would lose it silently).
//! * **Checks.** Node coordinates finite; node and element ids unique; every element's nodes
//!   exist; no two nodes of the body closer than `1e-9` times the body's bounding-box diagonal
//!   (an unmerged mesh; found with a spatial hash); a positive Jacobian determinant at each
//!   Gauss point of every solid (the points of its shape's standard rule,
//!   [`ElementFamily::standard`]); every face of a face set oriented out of its element.
//! * **Sides.** Abaqus side `Sn` of an element is the face of [`Shape::faces`] with the corners
//!   of the Abaqus/CalculiX face table of its shape (`abaqus_sides` here); a quadratic element's
//!   face carries its mid-side nodes. A side the shape does not have (`S5` of a tetrahedron)
//!   is [`ImportError::UnknownSide`].
//!
//! Every error names the file and, where it applies, the line (the byte offset in a binary MSH
//! file) and the entity: node id, element id, set name, Gauss point.

use super::{FaceSet, Mesh, MeshError};
use crate::element::{ElementFamily, Shape};
use nalgebra::{Matrix3, Vector3};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};

/// A node as the file states it.
#[derive(Clone, Debug, PartialEq)]
pub struct FileNode {
    /// The file's node id.
    pub id: u64,
    /// Coordinates.
    pub x: [f64; 3],
    /// Where it is stated: a global line number (a byte offset in a binary MSH file); see
    /// [`MeshFile::place`].
    pub line: usize,
}

/// A solid element as the file states it.
#[derive(Clone, Debug, PartialEq)]
pub struct FileElement {
    /// The file's element id.
    pub id: u64,
    /// Its shape.
    pub shape: Shape,
    /// File node ids, in fricsens node order.
    pub nodes: Vec<u64>,
    /// Where it is stated (see [`FileNode::line`]).
    pub line: usize,
}

/// A lower-dimensional element (point, line, triangle, quadrilateral, shell): it only defines
/// sets, and the nodes it references count as used.
#[derive(Clone, Debug, PartialEq)]
pub struct OtherElement {
    /// The file's element id.
    pub id: u64,
    /// Its kind as the file names it (`quad4`, `CPS4`, ...).
    pub kind: String,
    /// File node ids.
    pub nodes: Vec<u64>,
    /// Where it is stated (see [`FileNode::line`]).
    pub line: usize,
}

/// One face of a file's face set.
#[derive(Clone, Debug, PartialEq)]
pub enum FileFace {
    /// A face given by its nodes (a Gmsh surface element, an Abaqus shell element).
    Nodes {
        /// File node ids, in the file's order.
        nodes: Vec<u64>,
        /// Where it is stated (see [`FileNode::line`]).
        line: usize,
    },
    /// Side `side` of an element (Abaqus `S1`..`S6` -> 1..6).
    Side {
        /// The file's element id.
        element: u64,
        /// The side, 1-based.
        side: usize,
        /// Where it is stated (see [`FileNode::line`]).
        line: usize,
    },
}

impl FileFace {
    fn line(&self) -> usize {
        match self {
            FileFace::Nodes { line, .. } | FileFace::Side { line, .. } => *line,
        }
    }
}

/// Which mesh format a [`MeshFile`] was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Gmsh MSH 4.1 (ASCII or binary).
    Gmsh,
    /// Abaqus/CalculiX input file.
    Abaqus,
}

/// A position in a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loc {
    /// No particular position.
    None,
    /// A 1-based line.
    Line(usize),
    /// A byte offset (binary files).
    Byte(usize),
}

/// A file and a position in it, for messages (`mesh.msh, line 12`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Place {
    /// The file.
    pub file: PathBuf,
    /// The position.
    pub loc: Loc,
}

impl Place {
    /// A place with a line.
    pub fn line(file: &Path, line: usize) -> Self {
        Place {
            file: file.to_path_buf(),
            loc: Loc::Line(line),
        }
    }
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.loc {
            Loc::None => write!(f, "{}", self.file.display()),
            Loc::Line(l) => write!(f, "{}, line {l}", self.file.display()),
            Loc::Byte(b) => write!(f, "{}, byte {b}", self.file.display()),
        }
    }
}

/// Maps the global line numbers of a [`MeshFile`] (its included files read in place) back to
/// files and their lines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LineMap {
    /// The files, the main one first.
    pub files: Vec<PathBuf>,
    /// `(first global line, file index, its line there)`, in increasing global line.
    pub segments: Vec<(usize, usize, usize)>,
    /// Whether positions are byte offsets (binary MSH) rather than lines.
    pub bytes: bool,
}

/// Why a mesh file could not be read, imported or written.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ImportError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The system's message.
        message: String,
    },
    /// The file is not of a known mesh format (by extension).
    #[error(
        "{file}: unknown mesh format (by extension: .msh is Gmsh MSH 4.1, .inp is Abaqus/CalculiX)"
    )]
    UnknownFormat {
        /// The file.
        file: PathBuf,
    },
    /// The text (or binary data) does not follow the format.
    #[error("{at}: {message}")]
    Syntax {
        /// Where.
        at: Place,
        /// What is wrong.
        message: String,
    },
    /// The file ends inside a section.
    #[error("{at}: unexpected end of file ({context})")]
    Truncated {
        /// Where the file ends.
        at: Place,
        /// What was being read.
        context: String,
    },
    /// A Gmsh file of another MSH version than 4.1.
    #[error("{at}: MSH version {version}: only MSH 4.1 is read (write it with `gmsh -3 -format msh41 model.geo`, or `Mesh.MshFileVersion = 4.1;` in the script, `gmsh.option.setNumber(\"Mesh.MshFileVersion\", 4.1)` in the API)")]
    MshVersion {
        /// Where the version stands.
        at: Place,
        /// The version the file states.
        version: String,
    },
    /// An element type the reader does not take.
    #[error("{at}: unsupported element {kind} (supported: {supported})")]
    UnsupportedElement {
        /// Where.
        at: Place,
        /// The type as the file states it (`type 4, 4-node tetrahedron`; `C3D10`).
        kind: String,
        /// What the reader takes.
        supported: &'static str,
    },
    /// A keyword or construct the reader does not take.
    #[error("{at}: {what}")]
    Unsupported {
        /// Where.
        at: Place,
        /// What and what to do instead.
        what: String,
    },
    /// Two nodes with one id.
    #[error("{second}: node {node} is defined twice (first at {first})")]
    DuplicateNode {
        /// The id.
        node: u64,
        /// First definition.
        first: Place,
        /// Second definition.
        second: Place,
    },
    /// Two elements with one id.
    #[error("{second}: element {element} is defined twice (first at {first})")]
    DuplicateElement {
        /// The id.
        element: u64,
        /// First definition.
        first: Place,
        /// Second definition.
        second: Place,
    },
    /// An element names a node the file does not define.
    #[error("{at}: element {element} names node {node}, which the file does not define")]
    MissingNode {
        /// The element's definition.
        at: Place,
        /// The element id.
        element: u64,
        /// The missing node id.
        node: u64,
    },
    /// A set names a node or element the file does not define.
    #[error("{at}: set '{set}' names {what} {id}, which the file does not define")]
    MissingMember {
        /// Where.
        at: Place,
        /// The set.
        set: String,
        /// `node` or `element`.
        what: &'static str,
        /// The id.
        id: u64,
    },
    /// A node coordinate is NaN or infinite.
    #[error("{at}: node {node}: coordinates {x:?} are not finite")]
    NonFiniteNode {
        /// The node's definition.
        at: Place,
        /// The node id.
        node: u64,
        /// Its coordinates.
        x: [f64; 3],
    },
    /// A set name the file does not have.
    #[error("{file}: no element set '{set}' (the file has: {known})")]
    UnknownSet {
        /// The file.
        file: PathBuf,
        /// The name asked for.
        set: String,
        /// The element set names the file has (comma separated; `none` if none).
        known: String,
    },
    /// The body has no solid element.
    #[error("{file}: {what} has no solid element")]
    EmptyBody {
        /// The file.
        file: PathBuf,
        /// `element set 'X'` or `the file`.
        what: String,
    },
    /// A body mixes element shapes.
    #[error("{at}: element {element} is a {other}, but the body's first element is a {first} (a body has one shape: split it into element sets)")]
    MixedShapes {
        /// The first element of another shape.
        at: Place,
        /// Its id.
        element: u64,
        /// The body's first shape.
        first: &'static str,
        /// The other shape.
        other: &'static str,
    },
    /// Two body nodes at one place: the mesh is not merged.
    #[error("{second}: duplicate nodes: the mesh is not merged: nodes {a} ({first}) and {b} are {distance:e} apart (tolerance {tolerance:e}, 1e-9 of the body's bounding-box diagonal)")]
    CoincidentNodes {
        /// The first node id.
        a: u64,
        /// Its definition.
        first: Place,
        /// The second node id.
        b: u64,
        /// Its definition.
        second: Place,
        /// Their distance.
        distance: f64,
        /// The tolerance.
        tolerance: f64,
    },
    /// A node no element uses.
    #[error("{at}: node {node} is used by no element{why}")]
    UnusedNode {
        /// The node's definition.
        at: Place,
        /// The node id.
        node: u64,
        /// Why it matters (the node set holding it, or that Gmsh never writes one).
        why: String,
    },
    /// A solid with a non-positive Jacobian determinant (inverted or degenerate).
    #[error("{at}: element {element}: Jacobian determinant {det:e} <= 0 at Gauss point {gauss_point} (xi = {xi:?}): the element is inverted or degenerate")]
    InvertedElement {
        /// The element's definition.
        at: Place,
        /// The element id.
        element: u64,
        /// The Gauss point, in the order of the shape's standard rule (a hex8's in
        /// [`crate::element::hex8::gauss_points`] order).
        gauss_point: usize,
        /// Its natural coordinates.
        xi: [f64; 3],
        /// The determinant.
        det: f64,
    },
    /// A face of a face set is inside the body.
    #[error("{at}: face set '{set}': face {face} is not on the boundary (elements {a} and {b} share it)")]
    FaceNotOnBoundary {
        /// The face's definition.
        at: Place,
        /// The set.
        set: String,
        /// The face (`nodes [..]` or `side Sn of element e`).
        face: String,
        /// One element.
        a: u64,
        /// The other.
        b: u64,
    },
    /// A face of a face set is a face of no element of the file.
    #[error("{at}: face set '{set}': face {face} is a face of no element of the file")]
    FaceNotFound {
        /// The face's definition.
        at: Place,
        /// The set.
        set: String,
        /// The face (`nodes [..]` or `side Sn of element e`).
        face: String,
    },
    /// An Abaqus side the element's shape does not have.
    #[error("{at}: face set '{set}': element {element} is a {shape}, which has sides S1..S{sides}, not S{side}")]
    UnknownSide {
        /// The face's definition.
        at: Place,
        /// The set.
        set: String,
        /// The element id.
        element: u64,
        /// The element's shape.
        shape: &'static str,
        /// The side asked for (1-based).
        side: usize,
        /// How many sides the shape has.
        sides: usize,
    },
    /// A face whose normal does not point out of its element.
    #[error("{at}: face set '{set}': face {face} of element {element} does not point out of the element")]
    FaceOrientation {
        /// The face's definition.
        at: Place,
        /// The set.
        set: String,
        /// The face's nodes (file ids).
        face: String,
        /// The element id.
        element: u64,
    },
    /// A file set named like a generated one (`all`, `boundary`) that differs from it.
    #[error("{file}: the file's set '{set}' differs from the generated '{prefix}.{set}' (fricsens makes `.all` and `.boundary` itself: rename the file's set)")]
    ReservedSet {
        /// The file.
        file: PathBuf,
        /// The set name.
        set: String,
        /// The import prefix.
        prefix: String,
    },
    /// The mesh already has sets of the import's prefix.
    #[error("{file}: the mesh already has sets named '{prefix}.*': import with another prefix")]
    PrefixTaken {
        /// The file.
        file: PathBuf,
        /// The prefix.
        prefix: String,
    },
    /// An `*INCLUDE` cycle.
    #[error("{at}: *INCLUDE of {target} makes a cycle (it includes itself)")]
    IncludeCycle {
        /// The include line.
        at: Place,
        /// The included file.
        target: PathBuf,
    },
    /// The mesh refused the body.
    #[error("{file}: {source}")]
    Mesh {
        /// The file.
        file: PathBuf,
        /// The mesh's error.
        source: MeshError,
    },
    /// A mesh could not be written.
    #[error("{file}: cannot write: {message}")]
    Write {
        /// The file.
        file: PathBuf,
        /// Why.
        message: String,
    },
}

/// A mesh as its file states it: nodes, solid elements and named sets by file ids.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshFile {
    /// The file (for messages).
    pub path: PathBuf,
    /// The format it was read from.
    pub format: Format,
    /// Nodes, in file order.
    pub nodes: Vec<FileNode>,
    /// Solid elements, in file order.
    pub elements: Vec<FileElement>,
    /// Lower-dimensional elements (they define sets; their nodes count as used).
    pub other_elements: Vec<OtherElement>,
    /// Element sets: name -> indices into `elements` (Gmsh volume physical groups; Abaqus
    /// `ELSET`s, including `ELSET=` of `*ELEMENT`).
    pub element_sets: BTreeMap<String, Vec<usize>>,
    /// Node sets: name -> file node ids (Gmsh physical groups of any dimension: their
    /// elements' nodes; Abaqus `NSET`s and node-based surfaces).
    pub node_sets: BTreeMap<String, Vec<u64>>,
    /// Face sets (Gmsh physical surfaces: their quad/triangle elements; Abaqus element-based
    /// surfaces and `ELSET`s of shell/plane elements).
    pub face_sets: BTreeMap<String, Vec<FileFace>>,
    /// Global line numbers back to files and lines.
    pub lines: LineMap,
}

/// What `add_to` made of a body.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportedBody {
    /// The mesh group holding the body's elements.
    pub group: usize,
    /// Mesh node numbers of the body (in order of first appearance in its elements).
    pub nodes: Vec<usize>,
    /// File node id -> mesh node number.
    pub node_ids: BTreeMap<u64, usize>,
    /// File element id of each element of the group, in group order.
    pub element_ids: Vec<u64>,
}

/// Abaqus sides `S1`, `S2`, ... of a solid shape as 0-based local corner nodes: the face tables
/// of the Abaqus and CalculiX manuals (C3D8/C3D20: `S1 (1, 2, 3, 4)`, `S2 (5, 8, 7, 6)`,
/// `S3 (1, 5, 6, 2)`, `S4 (2, 6, 7, 3)`, `S5 (3, 7, 8, 4)`, `S6 (4, 8, 5, 1)`; C3D4/C3D10:
/// `S1 (1, 2, 3)`, `S2 (1, 4, 2)`, `S3 (2, 4, 3)`, `S4 (3, 4, 1)`; C3D6/C3D15: `S1 (1, 2, 3)`,
/// `S2 (4, 6, 5)`, `S3 (1, 4, 5, 2)`, `S4 (2, 5, 6, 3)`, `S5 (3, 6, 4, 1)`), corners only (a
/// quadratic element's side is the face of the same corners). None for a discrete shape.
pub(crate) fn abaqus_sides(shape: Shape) -> &'static [&'static [usize]] {
    const HEX: [&[usize]; 6] = [
        &[0, 1, 2, 3],
        &[4, 7, 6, 5],
        &[0, 4, 5, 1],
        &[1, 5, 6, 2],
        &[2, 6, 7, 3],
        &[3, 7, 4, 0],
    ];
    const TET: [&[usize]; 4] = [&[0, 1, 2], &[0, 3, 1], &[1, 3, 2], &[2, 3, 0]];
    const WEDGE: [&[usize]; 5] = [
        &[0, 1, 2],
        &[3, 5, 4],
        &[0, 3, 4, 1],
        &[1, 4, 5, 2],
        &[2, 5, 3, 0],
    ];
    match shape.corners() {
        Shape::Hex8 => &HEX,
        Shape::Tet4 => &TET,
        Shape::Wedge6 => &WEDGE,
        _ => &[],
    }
}

/// The face of [`Shape::faces`] (its index) with the corners of Abaqus side `side` (1-based)
/// of `shape`; `None` for a side the shape does not have.
pub(crate) fn face_of_side(shape: Shape, side: usize) -> Option<usize> {
    let corners = sorted(abaqus_sides(shape).get(side.checked_sub(1)?)?);
    shape
        .faces()
        .iter()
        .position(|f| sorted(&f.nodes[..f.family.n_corners()]) == corners)
}

/// The Abaqus side (1-based) of face `f` of [`Shape::faces`] of `shape`.
pub(crate) fn side_of_face(shape: Shape, f: usize) -> Option<usize> {
    (1..=abaqus_sides(shape).len()).find(|&s| face_of_side(shape, s) == Some(f))
}

fn sorted<T: Ord + Copy>(v: &[T]) -> Vec<T> {
    let mut k = v.to_vec();
    k.sort_unstable();
    k
}

/// Jacobian determinant of the reference map of a `shape` element with nodes `x` (in the
/// shape's node order) at natural coordinates `xi` (`NaN` for a discrete shape).
pub(crate) fn reference_det(shape: Shape, x: &[[f64; 3]], xi: [f64; 3]) -> f64 {
    let Some(solid) = ElementFamily::standard(shape).solid() else {
        return f64::NAN;
    };
    let d = (solid.interpolation.derivatives)(xi);
    let mut j = Matrix3::zeros();
    for (xa, da) in x.iter().zip(&d).take(solid.interpolation.n_nodes) {
        for r in 0..3 {
            for c in 0..3 {
                j[(r, c)] += xa[r] * da[c];
            }
        }
    }
    j.determinant()
}

/// Where a face of the file's solid elements is: up to two `(element index, face index)`.
type FaceOwners = HashMap<FaceKey, Vec<(usize, usize)>>;

/// A face by its sorted node ids, padded with `u64::MAX` (no allocation per face).
type FaceKey = [u64; super::MAX_FACE_NODES];

/// The key of the face with node ids `ids` (`None` for more nodes than any face has).
fn face_key(ids: impl Iterator<Item = u64>) -> Option<FaceKey> {
    let mut k = [u64::MAX; super::MAX_FACE_NODES];
    let mut n = 0;
    for id in ids {
        *k.get_mut(n)? = id;
        n += 1;
    }
    k[..n].sort_unstable();
    Some(k)
}

impl MeshFile {
    /// An empty file of `format` at `path`.
    pub(crate) fn empty(path: &Path, format: Format, bytes: bool) -> Self {
        MeshFile {
            path: path.to_path_buf(),
            format,
            nodes: Vec::new(),
            elements: Vec::new(),
            other_elements: Vec::new(),
            element_sets: BTreeMap::new(),
            node_sets: BTreeMap::new(),
            face_sets: BTreeMap::new(),
            lines: LineMap {
                files: vec![path.to_path_buf()],
                segments: vec![(0, 0, 0)],
                bytes,
            },
        }
    }

    /// The file and position of global line `line` (a byte offset in a binary MSH file).
    pub fn place(&self, line: usize) -> Place {
        if self.lines.bytes {
            return Place {
                file: self.path.clone(),
                loc: Loc::Byte(line),
            };
        }
        let k = self
            .lines
            .segments
            .partition_point(|s| s.0 <= line)
            .saturating_sub(1);
        match self.lines.segments.get(k) {
            Some(&(start, f, local)) => Place {
                file: self.lines.files.get(f).unwrap_or(&self.path).clone(),
                loc: Loc::Line(local + line.saturating_sub(start)),
            },
            None => Place::line(&self.path, line),
        }
    }

    /// Every element, node and face set name, sorted and without repetition (for messages).
    pub fn set_names(&self) -> Vec<String> {
        let mut s: BTreeSet<String> = BTreeSet::new();
        s.extend(self.element_sets.keys().cloned());
        s.extend(self.node_sets.keys().cloned());
        s.extend(self.face_sets.keys().cloned());
        s.into_iter().collect()
    }

    /// The element set called `name` (case-insensitively for Abaqus files).
    fn element_set(&self, name: &str) -> Result<&Vec<usize>, ImportError> {
        if let Some(s) = self.element_sets.get(name) {
            return Ok(s);
        }
        if self.format == Format::Abaqus {
            if let Some((_, s)) = self
                .element_sets
                .iter()
                .find(|(k, _)| k.eq_ignore_ascii_case(name))
            {
                return Ok(s);
            }
        }
        let known: Vec<&str> = self.element_sets.keys().map(String::as_str).collect();
        Err(ImportError::UnknownSet {
            file: self.path.clone(),
            set: name.to_string(),
            known: if known.is_empty() {
                "none".into()
            } else {
                known.join(", ")
            },
        })
    }

    /// Node id -> index into `nodes`; typed errors for a repeated id or a non-finite node.
    fn node_index(&self) -> Result<HashMap<u64, usize>, ImportError> {
        let mut index: HashMap<u64, usize> = HashMap::with_capacity(self.nodes.len());
        for (k, n) in self.nodes.iter().enumerate() {
            if let Some(&first) = index.get(&n.id) {
                return Err(ImportError::DuplicateNode {
                    node: n.id,
                    first: self.place(self.nodes[first].line),
                    second: self.place(n.line),
                });
            }
            if !n.x.iter().all(|c| c.is_finite()) {
                return Err(ImportError::NonFiniteNode {
                    at: self.place(n.line),
                    node: n.id,
                    x: n.x,
                });
            }
            index.insert(n.id, k);
        }
        Ok(index)
    }

    /// Element id -> index into `elements`; checks ids unique (solid and other elements)
    /// and that every element's nodes exist.
    fn element_index(
        &self,
        nodes: &HashMap<u64, usize>,
    ) -> Result<HashMap<u64, usize>, ImportError> {
        let mut index: HashMap<u64, usize> = HashMap::with_capacity(self.elements.len());
        let mut lines: HashMap<u64, usize> = HashMap::new();
        let all = self
            .elements
            .iter()
            .map(|e| (e.id, &e.nodes, e.line))
            .chain(self.other_elements.iter().map(|e| (e.id, &e.nodes, e.line)));
        let sizes = self
            .elements
            .iter()
            .map(|e| Some(e.shape.n_nodes()))
            .chain(self.other_elements.iter().map(|_| None));
        for (k, ((id, enodes, line), size)) in all.zip(sizes).enumerate() {
            if size.is_some_and(|n| n != enodes.len()) {
                return Err(ImportError::Syntax {
                    at: self.place(line),
                    message: format!(
                        "element {id}: {} nodes for a {}",
                        enodes.len(),
                        self.elements[k].shape.name()
                    ),
                });
            }
            if let Some(&first) = lines.get(&id) {
                return Err(ImportError::DuplicateElement {
                    element: id,
                    first: self.place(first),
                    second: self.place(line),
                });
            }
            lines.insert(id, line);
            if k < self.elements.len() {
                index.insert(id, k);
            }
            if let Some(&n) = enodes.iter().find(|n| !nodes.contains_key(n)) {
                return Err(ImportError::MissingNode {
                    at: self.place(line),
                    element: id,
                    node: n,
                });
            }
        }
        Ok(index)
    }

    /// Sorted face node ids -> the solid elements (index, face) that have the face.
    fn face_owners(&self) -> FaceOwners {
        let mut owners: FaceOwners = HashMap::new();
        for (k, e) in self.elements.iter().enumerate() {
            for (f, face) in e.shape.faces().iter().enumerate() {
                let Some(key) =
                    face_key(face.nodes.iter().filter_map(|&l| e.nodes.get(l).copied()))
                else {
                    continue;
                };
                let v = owners.entry(key).or_default();
                if v.len() < 3 {
                    v.push((k, f));
                }
            }
        }
        owners
    }

    /// Add the solid elements of element set `set` (every solid element when `None`) to
    /// `mesh` as one new group, with new nodes, and the file's sets restricted to the body as
    /// `"{prefix}.{name}"` (see the module documentation for the rules and checks).
    pub fn add_to(
        &self,
        mesh: &mut Mesh,
        prefix: &str,
        set: Option<&str>,
    ) -> Result<ImportedBody, ImportError> {
        let node_index = self.node_index()?;
        let element_index = self.element_index(&node_index)?;
        // the body's elements
        let body: Vec<usize> = match set {
            None => (0..self.elements.len()).collect(),
            Some(name) => {
                let mut v = self.element_set(name)?.clone();
                v.sort_unstable();
                v.dedup();
                v
            }
        };
        let body: Vec<usize> = body
            .into_iter()
            .filter(|&k| k < self.elements.len())
            .collect();
        let Some(&first) = body.first() else {
            return Err(ImportError::EmptyBody {
                file: self.path.clone(),
                what: match set {
                    Some(s) => format!("element set '{s}'"),
                    None => "the file".into(),
                },
            });
        };
        let shape = self.elements[first].shape;
        if let Some(&k) = body.iter().find(|&&k| self.elements[k].shape != shape) {
            let e = &self.elements[k];
            return Err(ImportError::MixedShapes {
                at: self.place(e.line),
                element: e.id,
                first: shape.name(),
                other: e.shape.name(),
            });
        }
        // body nodes, in order of first appearance
        let mut node_ids: BTreeMap<u64, usize> = BTreeMap::new();
        let mut body_nodes: Vec<usize> = Vec::new(); // indices into self.nodes
        let mut local: HashMap<u64, usize> = HashMap::new(); // id -> index into body_nodes
        for &k in &body {
            for id in &self.elements[k].nodes {
                if !local.contains_key(id) {
                    local.insert(*id, body_nodes.len());
                    body_nodes.push(node_index[id]);
                }
            }
        }
        self.check_unused(&node_index, &local)?;
        self.check_coincident(&body_nodes)?;
        for &k in &body {
            self.check_jacobian(&self.elements[k], &node_index)?;
        }
        let taken = format!("{prefix}.");
        if mesh
            .node_sets
            .keys()
            .chain(mesh.face_sets.keys())
            .any(|k| k.starts_with(&taken))
        {
            return Err(ImportError::PrefixTaken {
                file: self.path.clone(),
                prefix: prefix.to_string(),
            });
        }
        // the body's mesh numbers and sets, before the mesh changes
        let base = mesh.n_nodes();
        let mut mesh_nodes = Vec::with_capacity(body_nodes.len());
        for (i, &n) in body_nodes.iter().enumerate() {
            mesh_nodes.push(base + i);
            node_ids.insert(self.nodes[n].id, base + i);
        }
        let in_body: Vec<bool> = {
            let mut v = vec![false; self.elements.len()];
            for &k in &body {
                v[k] = true;
            }
            v
        };
        let owners = self.face_owners();
        let (mut node_sets, mut face_sets) =
            self.body_sets(&node_ids, &node_index, &element_index, &in_body, &owners)?;
        // the boundary faces point out of their elements too
        for &k in &body {
            let e = &self.elements[k];
            for face in e.shape.faces() {
                let ids: Vec<u64> = face.nodes.iter().map(|&l| e.nodes[l]).collect();
                let on_body = owners
                    .get(&face_key(ids.iter().copied()).unwrap_or_default())
                    .map_or(0, |v| v.iter().filter(|&&(j, _)| in_body[j]).count());
                if on_body == 1 {
                    let corners = &ids[..face.family.n_corners()];
                    self.check_outward("boundary", e.line, e, corners, &node_index)?;
                }
            }
        }
        let reserved = |set: &str| ImportError::ReservedSet {
            file: self.path.clone(),
            set: set.into(),
            prefix: prefix.into(),
        };
        if face_sets.contains_key("all") {
            return Err(reserved("all"));
        }
        let mut all = mesh_nodes.clone();
        all.sort_unstable();
        if node_sets.remove("all").is_some_and(|mine| mine != all) {
            return Err(reserved("all"));
        }
        // into the mesh (undone on a later error)
        let groups = mesh.groups.len();
        for &n in &body_nodes {
            mesh.add_node(self.nodes[n].x);
        }
        let mut connectivity = Vec::with_capacity(body.len() * shape.n_nodes());
        for &k in &body {
            connectivity.extend(self.elements[k].nodes.iter().map(|id| node_ids[id]));
        }
        let undo = |mesh: &mut Mesh, e: ImportError| {
            mesh.places.truncate(base);
            mesh.groups.truncate(groups);
            e
        };
        let group = match mesh.add_group(shape, connectivity) {
            Ok(g) => g,
            Err(source) => {
                let file = self.path.clone();
                return Err(undo(mesh, ImportError::Mesh { file, source }));
            }
        };
        let boundary = mesh.boundary_faces(group);
        let mut boundary_nodes = boundary.all_nodes().to_vec();
        boundary_nodes.sort_unstable();
        boundary_nodes.dedup();
        if node_sets
            .remove("boundary")
            .is_some_and(|mine| mine != boundary_nodes)
        {
            return Err(undo(mesh, reserved("boundary")));
        }
        if let Some(mine) = face_sets.remove("boundary") {
            let keys = |s: &FaceSet| {
                let mut v: Vec<Vec<usize>> = s.iter().map(|f| sorted(f.nodes)).collect();
                v.sort();
                v
            };
            if keys(&mine) != keys(&boundary) {
                return Err(undo(mesh, reserved("boundary")));
            }
        }
        mesh.node_sets.insert(format!("{prefix}.all"), all);
        mesh.node_sets
            .insert(format!("{prefix}.boundary"), boundary_nodes);
        mesh.face_sets
            .insert(format!("{prefix}.boundary"), boundary);
        for (name, nodes) in node_sets {
            mesh.node_sets.insert(format!("{prefix}.{name}"), nodes);
        }
        for (name, faces) in face_sets {
            mesh.face_sets.insert(format!("{prefix}.{name}"), faces);
        }
        Ok(ImportedBody {
            group,
            nodes: mesh_nodes,
            node_ids,
            element_ids: body.iter().map(|&k| self.elements[k].id).collect(),
        })
    }

    /// The unused-node rule (module documentation).
    fn check_unused(
        &self,
        node_index: &HashMap<u64, usize>,
        body: &HashMap<u64, usize>,
    ) -> Result<(), ImportError> {
        let mut used = vec![false; self.nodes.len()];
        let all = self
            .elements
            .iter()
            .map(|e| &e.nodes)
            .chain(self.other_elements.iter().map(|e| &e.nodes));
        for nodes in all {
            for id in nodes {
                if let Some(&k) = node_index.get(id) {
                    used[k] = true;
                }
            }
        }
        match self.format {
            Format::Gmsh => {
                if let Some(k) = used.iter().position(|u| !u) {
                    let n = &self.nodes[k];
                    return Err(ImportError::UnusedNode {
                        at: self.place(n.line),
                        node: n.id,
                        why: " (Gmsh writes no such node: the file is damaged)".into(),
                    });
                }
            }
            Format::Abaqus => {
                for (name, ids) in &self.node_sets {
                    if !ids.iter().any(|id| body.contains_key(id)) {
                        continue;
                    }
                    for id in ids {
                        if let Some(&k) = node_index.get(id) {
                            if !used[k] {
                                return Err(ImportError::UnusedNode {
                                    at: self.place(self.nodes[k].line),
                                    node: *id,
                                    why: format!(
                                        ", yet node set '{name}' holds it with nodes of the body"
                                    ),
                                });
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// No two body nodes closer than 1e-9 of the body's bounding-box diagonal.
    fn check_coincident(&self, body_nodes: &[usize]) -> Result<(), ImportError> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &n in body_nodes {
            for c in 0..3 {
                lo[c] = lo[c].min(self.nodes[n].x[c]);
                hi[c] = hi[c].max(self.nodes[n].x[c]);
            }
        }
        let diag = (0..3).map(|c| (hi[c] - lo[c]).powi(2)).sum::<f64>().sqrt();
        let tol = 1e-9 * diag;
        if !tol.is_finite() {
            return Ok(());
        }
        let h = if tol > 0.0 { tol } else { 1.0 };
        let cell =
            |x: &[f64; 3]| -> [i64; 3] { [0, 1, 2].map(|c| ((x[c] - lo[c]) / h).floor() as i64) };
        let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
        for &n in body_nodes {
            let x = &self.nodes[n].x;
            let c = cell(x);
            for dx in -1..=1i64 {
                for dy in -1..=1i64 {
                    for dz in -1..=1i64 {
                        let key = [
                            c[0].saturating_add(dx),
                            c[1].saturating_add(dy),
                            c[2].saturating_add(dz),
                        ];
                        for &m in grid.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
                            let y = &self.nodes[m].x;
                            let d = (0..3).map(|k| (x[k] - y[k]).powi(2)).sum::<f64>().sqrt();
                            if d <= tol {
                                let (a, b) = (&self.nodes[m], &self.nodes[n]);
                                return Err(ImportError::CoincidentNodes {
                                    a: a.id,
                                    first: self.place(a.line),
                                    b: b.id,
                                    second: self.place(b.line),
                                    distance: d,
                                    tolerance: tol,
                                });
                            }
                        }
                    }
                }
            }
            grid.entry(c).or_default().push(n);
        }
        Ok(())
    }

    /// Positive Jacobian determinant at every Gauss point of the shape's standard rule.
    fn check_jacobian(
        &self,
        e: &FileElement,
        node_index: &HashMap<u64, usize>,
    ) -> Result<(), ImportError> {
        let Some(solid) = ElementFamily::standard(e.shape).solid() else {
            return Ok(());
        };
        let x: Vec<[f64; 3]> = e
            .nodes
            .iter()
            .map(|id| self.nodes[node_index[id]].x)
            .collect();
        for (g, &xi) in solid.rule.points.iter().enumerate() {
            let det = reference_det(e.shape, &x, xi);
            if det.is_nan() || det <= 0.0 {
                return Err(ImportError::InvertedElement {
                    at: self.place(e.line),
                    element: e.id,
                    gauss_point: g,
                    xi,
                    det,
                });
            }
        }
        Ok(())
    }

    /// The file's node and face sets restricted to the body (names without the prefix).
    #[allow(clippy::type_complexity)]
    fn body_sets(
        &self,
        node_ids: &BTreeMap<u64, usize>,
        node_index: &HashMap<u64, usize>,
        element_index: &HashMap<u64, usize>,
        in_body: &[bool],
        owners: &FaceOwners,
    ) -> Result<(BTreeMap<String, Vec<usize>>, BTreeMap<String, FaceSet>), ImportError> {
        let mut node_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        let restrict = |ids: &mut dyn Iterator<Item = u64>| -> Vec<usize> {
            let mut v: Vec<usize> = ids.filter_map(|id| node_ids.get(&id).copied()).collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        for (name, ids) in &self.node_sets {
            let v = restrict(&mut ids.iter().copied());
            if !v.is_empty() {
                node_sets.insert(name.clone(), v);
            }
        }
        let has_node_set = |name: &str| {
            self.node_sets.contains_key(name)
                || (self.format == Format::Abaqus
                    && self.node_sets.keys().any(|k| k.eq_ignore_ascii_case(name)))
        };
        // element sets also give node sets (of their body elements) unless one exists
        for (name, elements) in &self.element_sets {
            if has_node_set(name) {
                continue;
            }
            let v = restrict(
                &mut elements
                    .iter()
                    .filter(|&&k| in_body.get(k) == Some(&true))
                    .flat_map(|&k| self.elements[k].nodes.iter().copied()),
            );
            if !v.is_empty() {
                node_sets.insert(name.clone(), v);
            }
        }
        let mut face_sets: BTreeMap<String, FaceSet> = BTreeMap::new();
        for (name, faces) in &self.face_sets {
            let mut set = FaceSet::new();
            let mut seen: BTreeSet<(usize, usize)> = BTreeSet::new();
            for face in faces {
                let Some((k, f)) = self.resolve_face(name, face, owners, element_index, in_body)?
                else {
                    continue;
                };
                if !seen.insert((k, f)) {
                    continue;
                }
                let e = &self.elements[k];
                let topo = &e.shape.faces()[f];
                let ids: Vec<u64> = topo.nodes.iter().map(|&l| e.nodes[l]).collect();
                let corners = &ids[..topo.family.n_corners()];
                self.check_outward(name, face.line(), e, corners, node_index)?;
                let nodes: Vec<usize> = ids.iter().map(|id| node_ids[id]).collect();
                set.push(topo.family, &nodes)
                    .map_err(|source| ImportError::Mesh {
                        file: self.path.clone(),
                        source,
                    })?;
            }
            if set.is_empty() {
                continue;
            }
            if !has_node_set(name) {
                let mut nodes = set.all_nodes().to_vec();
                nodes.sort_unstable();
                nodes.dedup();
                node_sets.insert(name.clone(), nodes);
            }
            face_sets.insert(name.clone(), set);
        }
        Ok((node_sets, face_sets))
    }

    /// The body element and face a file face names; `None` when it is another body's.
    fn resolve_face(
        &self,
        set: &str,
        face: &FileFace,
        owners: &FaceOwners,
        element_index: &HashMap<u64, usize>,
        in_body: &[bool],
    ) -> Result<Option<(usize, usize)>, ImportError> {
        let at = self.place(face.line());
        let (key, label) = match face {
            FileFace::Nodes { nodes, .. } => (
                face_key(nodes.iter().copied()).unwrap_or_default(),
                format!("nodes {nodes:?}"),
            ),
            FileFace::Side { element, side, .. } => {
                let label = format!("side S{side} of element {element}");
                let not_found = || ImportError::FaceNotFound {
                    at: at.clone(),
                    set: set.to_string(),
                    face: label.clone(),
                };
                let Some(&k) = element_index.get(element) else {
                    return Err(not_found());
                };
                let e = &self.elements[k];
                let Some(f) = face_of_side(e.shape, *side) else {
                    return Err(ImportError::UnknownSide {
                        at,
                        set: set.to_string(),
                        element: *element,
                        shape: e.shape.name(),
                        side: *side,
                        sides: abaqus_sides(e.shape).len(),
                    });
                };
                let ids: Vec<u64> = e.shape.faces()[f]
                    .nodes
                    .iter()
                    .map(|&l| e.nodes[l])
                    .collect();
                (face_key(ids.iter().copied()).unwrap_or_default(), label)
            }
        };
        let Some(list) = owners.get(&key) else {
            return Err(ImportError::FaceNotFound {
                at,
                set: set.to_string(),
                face: label,
            });
        };
        let mine: Vec<(usize, usize)> = list
            .iter()
            .copied()
            .filter(|&(k, _)| in_body.get(k) == Some(&true))
            .collect();
        match mine.as_slice() {
            [] => Ok(None),
            [one] => Ok(Some(*one)),
            [a, b, ..] => Err(ImportError::FaceNotOnBoundary {
                at,
                set: set.to_string(),
                face: label,
                a: self.elements[a.0].id,
                b: self.elements[b.0].id,
            }),
        }
    }

    /// The face of corners `ids` (in the face's cyclic order) of element `e` points out of
    /// it: (face centre - element centre) . n > 0, the element centre the mean of its corners.
    fn check_outward(
        &self,
        set: &str,
        line: usize,
        e: &FileElement,
        ids: &[u64],
        node_index: &HashMap<u64, usize>,
    ) -> Result<(), ImportError> {
        let pos = |id: &u64| Vector3::from(self.nodes[node_index[id]].x);
        let corners = &e.nodes[..e.shape.corners().n_nodes().min(e.nodes.len())];
        let xe: Vector3<f64> =
            corners.iter().map(pos).sum::<Vector3<f64>>() / corners.len().max(1) as f64;
        let xf: Vec<Vector3<f64>> = ids.iter().map(pos).collect();
        let centre = xf.iter().sum::<Vector3<f64>>() / xf.len().max(1) as f64;
        // the face normal: sum of the corner cross products (Newell), any polygon
        let mut normal = Vector3::zeros();
        for a in 0..xf.len() {
            let b = (a + 1) % xf.len();
            normal += (xf[a] - centre).cross(&(xf[b] - centre));
        }
        let out = (centre - xe).dot(&normal);
        if out.is_nan() || out <= 0.0 {
            return Err(ImportError::FaceOrientation {
                at: self.place(line),
                set: set.to_string(),
                face: format!("{ids:?}"),
                element: e.id,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The natural nodes of `shape` mapped by `x -> (a x, b y, c z) + d`: an affine map of
    /// determinant `a b c`.
    fn stretched(shape: Shape, abc: [f64; 3]) -> Vec<[f64; 3]> {
        shape
            .natural_nodes()
            .iter()
            .map(|p| {
                [
                    abc[0] * p[0] + 1.0,
                    abc[1] * p[1] - 2.0,
                    abc[2] * p[2] + 0.5,
                ]
            })
            .collect()
    }

    #[test]
    fn the_jacobian_of_an_affine_map_is_its_determinant_for_every_shape() {
        // an affine image of the natural element: det J = a b c at every point, -a b c mirrored
        for shape in Shape::SOLIDS {
            let x = stretched(shape, [1.0, 1.5, 2.5]);
            let m = stretched(shape, [-1.0, 1.5, 2.5]);
            let solid = ElementFamily::standard(shape).solid().unwrap();
            for &xi in solid.rule.points {
                assert!(
                    (reference_det(shape, &x, xi) - 3.75).abs() < 1e-13,
                    "{shape:?}"
                );
                assert!(
                    (reference_det(shape, &m, xi) + 3.75).abs() < 1e-13,
                    "{shape:?}"
                );
            }
        }
        assert!(reference_det(Shape::Line2, &[[0.0; 3]; 2], [0.0; 3]).is_nan());
    }

    #[test]
    fn abaqus_sides_are_faces_of_their_shapes_one_for_one() {
        // the manuals' tables as 1-based corners, each side's face holds exactly them
        let tables: [(Shape, &[&[usize]]); 3] = [
            (
                Shape::Hex8,
                &[
                    &[1, 2, 3, 4],
                    &[5, 8, 7, 6],
                    &[1, 5, 6, 2],
                    &[2, 6, 7, 3],
                    &[3, 7, 8, 4],
                    &[4, 8, 5, 1],
                ],
            ),
            (
                Shape::Tet4,
                &[&[1, 2, 3], &[1, 4, 2], &[2, 4, 3], &[3, 4, 1]],
            ),
            (
                Shape::Wedge6,
                &[
                    &[1, 2, 3],
                    &[4, 6, 5],
                    &[1, 4, 5, 2],
                    &[2, 5, 6, 3],
                    &[3, 6, 4, 1],
                ],
            ),
        ];
        for (linear, table) in tables {
            for shape in Shape::SOLIDS.into_iter().filter(|s| s.corners() == linear) {
                assert_eq!(abaqus_sides(shape).len(), table.len());
                let mut seen = vec![false; shape.faces().len()];
                for (k, corners) in table.iter().enumerate() {
                    let f = face_of_side(shape, k + 1).unwrap();
                    assert!(!seen[f], "{shape:?} S{}", k + 1);
                    seen[f] = true;
                    assert_eq!(side_of_face(shape, f), Some(k + 1));
                    let face = &shape.faces()[f];
                    let mut got = face.nodes[..face.family.n_corners()].to_vec();
                    got.sort_unstable();
                    let mut want: Vec<usize> = corners.iter().map(|c| c - 1).collect();
                    want.sort_unstable();
                    assert_eq!(got, want, "{shape:?} S{}", k + 1);
                }
                assert!(seen.iter().all(|&s| s), "{shape:?}");
                assert_eq!(face_of_side(shape, 0), None);
                assert_eq!(face_of_side(shape, table.len() + 1), None);
            }
        }
        // S1 of a hex8 is its -z face (nodes 1-4), fricsens face 4
        assert_eq!(face_of_side(Shape::Hex8, 1), Some(4));
        assert!(abaqus_sides(Shape::Point1).is_empty());
    }

    #[test]
    fn face_keys_ignore_the_node_order_and_refuse_too_many_nodes() {
        assert_eq!(
            face_key([4, 1, 3, 2].into_iter()),
            face_key([1, 2, 3, 4].into_iter())
        );
        assert_ne!(
            face_key([1, 2, 3].into_iter()),
            face_key([1, 2, 3, 4].into_iter())
        );
        assert_eq!(face_key(0..9), None);
    }

    #[test]
    fn places_map_global_lines_back_to_included_files() {
        let mut f = MeshFile::empty(Path::new("a.inp"), Format::Abaqus, false);
        f.lines.files.push("b.inp".into());
        // a.inp lines 1-3, b.inp lines 1-2 (global 4-5), a.inp from line 4 (global 6)
        f.lines.segments = vec![(1, 0, 1), (4, 1, 1), (6, 0, 4)];
        assert_eq!(f.place(2).to_string(), "a.inp, line 2");
        assert_eq!(f.place(5).to_string(), "b.inp, line 2");
        assert_eq!(f.place(7).to_string(), "a.inp, line 5");
        f.lines.bytes = true;
        assert_eq!(f.place(7).to_string(), "a.inp, byte 7");
    }
}
