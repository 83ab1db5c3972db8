//! Gmsh MSH 4.1 meshes, ASCII and binary: reader and writer (see [`super::import`] for how a
//! read file enters a mesh).
//!
//! The reader is written here rather than taken from the `mshio` crate so that every error
//! names the file, the line (the byte offset in a binary file) and the entity (node, element,
//! entity tag). It reads the sections `$MeshFormat`, `$PhysicalNames`, `$Entities`, `$Nodes`
//! and `$Elements`, and skips any other (`$PartitionedEntities`, `$Periodic`, `$NodeData`,
//! `$Comments`, ...). MSH 2.2 and 4.0 are refused with a typed error that says how to write
//! 4.1. Binary files of either byte order are read (the integer 1 after the format line
//! tells which).
//!
//! Element types: 4 (4-node tetrahedron, tet4), 11 (10-node tetrahedron, tet10), 5 (8-node
//! hexahedron, hex8), 17 (20-node hexahedron, hex20), 6 (6-node prism, wedge6) and 18 (15-node
//! prism, wedge15) are solids; 15 (point), 1 and 8 (2- and 3-node lines), 2 and 9 (3- and
//! 6-node triangles), 3 and 16 (4- and 8-node quadrangles) define sets; any other type
//! (27-node hexahedra, 18-node prisms, pyramids, ...) is [`ImportError::UnsupportedElement`].
//!
//! Node order: Gmsh numbers the corners as fricsens does, and its mid-edge nodes otherwise:
//! the reader permutes each solid's nodes into fricsens' order (`gmsh_order`) and the writer
//! back. Gmsh's reference nodes (`gmsh.model.mesh.getElementProperties`, the "node ordering"
//! section of the Gmsh manual) at fricsens' natural coordinates give the permutations:
//! tet10 lists the mid-edge nodes of edges `01, 12, 20, 03, 23, 13` (fricsens: `01, 12, 20,
//! 03, 13, 23`: the last two swapped); hex20 those of `01, 03, 04, 12, 15, 23, 26, 37, 45, 47,
//! 56, 67` (fricsens: `01, 12, 23, 30, 45, 56, 67, 74, 04, 15, 26, 37`); wedge15 those of `01,
//! 02, 03, 12, 14, 25, 34, 35, 45` (fricsens: `01, 12, 20, 34, 45, 53, 03, 14, 25`). The
//! surface types number as fricsens' face families.
//!
//! Sets: a physical group of dimension 3 is an element set (its solids) and a node set
//! (their nodes); of dimension 2 a face set (its triangles and quadrangles) and a node set; of
//! dimension 1 or 0 a node set. Its name is the one `$PhysicalNames` gives, or, for an unnamed
//! group, the name Gmsh itself gives it in its Abaqus and UNV exports: `PhysicalPoint{tag}`,
//! `PhysicalLine{tag}`, `PhysicalSurface{tag}`, `PhysicalVolume{tag}` (so a model exported
//! as `.msh` and as `.inp` has the same set names). Groups of one name in several dimensions
//! share one node set (the union). A file without physical groups has no sets: import all its
//! solids with `add_to(.., None)`.
//!
//! The writer writes each body (of any solid shape) as a volume entity and physical volume of
//! its name, its nodes in Gmsh's order, each face set `BODY.NAME` as a surface entity in
//! physical surface `NAME` (triangles and quadrangles of its faces' families, outward), each
//! node set `BODY.NAME` as a point entity in physical point `NAME` (one point
//! element per node). Coordinates are written in Rust's shortest round-trip form, so an ASCII
//! file reads back bit for bit, like a binary one.

use super::import::{FileElement, FileFace, Format, ImportError, MeshFile, OtherElement, Place};
use super::Mesh;
use crate::element::{FaceFamily, Shape};
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// What this reader takes.
const SUPPORTED: &str = "types 4 (4-node tetrahedron), 11 (10-node tetrahedron), 5 (8-node hexahedron), 17 (20-node hexahedron), 6 (6-node prism), 18 (15-node prism) as solids; types 15 (point), 1 (2-node line), 8 (3-node line), 2 (3-node triangle), 9 (6-node triangle), 3 (4-node quadrangle), 16 (8-node quadrangle) for sets";

/// The solid shape of a Gmsh element type (`None` for the others).
fn solid_shape(t: i64) -> Option<Shape> {
    Some(match t {
        4 => Shape::Tet4,
        11 => Shape::Tet10,
        5 => Shape::Hex8,
        17 => Shape::Hex20,
        6 => Shape::Wedge6,
        18 => Shape::Wedge15,
        _ => return None,
    })
}

/// The Gmsh element type of a solid shape (`None` for a discrete one).
fn solid_type(shape: Shape) -> Option<i32> {
    Some(match shape {
        Shape::Tet4 => 4,
        Shape::Tet10 => 11,
        Shape::Hex8 => 5,
        Shape::Hex20 => 17,
        Shape::Wedge6 => 6,
        Shape::Wedge15 => 18,
        Shape::Point1 | Shape::Line2 => return None,
    })
}

/// The Gmsh element type of a face family.
fn face_type(family: FaceFamily) -> i32 {
    match family {
        FaceFamily::Tri3 => 2,
        FaceFamily::Tri6 => 9,
        FaceFamily::Quad4 => 3,
        FaceFamily::Quad8 => 16,
    }
}

/// Gmsh's node order of a solid shape: fricsens node `k` is Gmsh node `gmsh_order(shape)[k]`
/// (the reader's permutation; the writer writes Gmsh node `gmsh_order[k]` from fricsens node
/// `k`). Corners are numbered alike; the mid-edge nodes differ (module documentation).
pub(crate) fn gmsh_order(shape: Shape) -> &'static [usize] {
    const TET10: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];
    const HEX20: [usize; 20] = [
        0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 9, 16, 18, 19, 17, 10, 12, 14, 15,
    ];
    const WEDGE15: [usize; 15] = [0, 1, 2, 3, 4, 5, 6, 9, 7, 12, 14, 13, 8, 10, 11];
    const IDENTITY: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 7];
    match shape {
        Shape::Tet10 => &TET10,
        Shape::Hex20 => &HEX20,
        Shape::Wedge15 => &WEDGE15,
        s => &IDENTITY[..s.n_nodes().min(8)],
    }
}

/// Name, node count and dimension of a Gmsh element type.
fn element_type(t: i64) -> Option<(&'static str, usize, i64)> {
    Some(match t {
        1 => ("2-node line", 2, 1),
        2 => ("3-node triangle", 3, 2),
        3 => ("4-node quadrangle", 4, 2),
        4 => ("4-node tetrahedron", 4, 3),
        5 => ("8-node hexahedron", 8, 3),
        6 => ("6-node prism", 6, 3),
        7 => ("5-node pyramid", 5, 3),
        8 => ("3-node second order line", 3, 1),
        9 => ("6-node second order triangle", 6, 2),
        10 => ("9-node second order quadrangle", 9, 2),
        11 => ("10-node second order tetrahedron", 10, 3),
        12 => ("27-node second order hexahedron", 27, 3),
        13 => ("18-node second order prism", 18, 3),
        14 => ("14-node second order pyramid", 14, 3),
        15 => ("1-node point", 1, 0),
        16 => ("8-node second order quadrangle", 8, 2),
        17 => ("20-node second order hexahedron", 20, 3),
        18 => ("15-node second order prism", 15, 3),
        19 => ("13-node second order pyramid", 13, 3),
        _ => return None,
    })
}

/// Short name of a supported lower-dimensional type.
fn short_name(t: i64) -> &'static str {
    match t {
        1 => "line2",
        8 => "line3",
        2 => "tri3",
        9 => "tri6",
        3 => "quad4",
        16 => "quad8",
        _ => "point1",
    }
}

/// A cursor over the file's bytes, ASCII or binary.
struct Cur<'a> {
    b: &'a [u8],
    pos: usize,
    line: usize,
    path: &'a Path,
    binary: bool,
    big_endian: bool,
    size_t: usize,
}

type R<T> = Result<T, ImportError>;

impl<'a> Cur<'a> {
    /// The current position: a line, or a byte offset in a binary file.
    fn at(&self) -> usize {
        if self.binary {
            self.pos
        } else {
            self.line
        }
    }

    fn place_of(&self, at: usize) -> Place {
        Place {
            file: self.path.to_path_buf(),
            loc: if self.binary {
                super::import::Loc::Byte(at)
            } else {
                super::import::Loc::Line(at)
            },
        }
    }

    fn syntax(&self, at: usize, message: impl Into<String>) -> ImportError {
        ImportError::Syntax {
            at: self.place_of(at),
            message: message.into(),
        }
    }

    fn truncated(&self, context: &str) -> ImportError {
        ImportError::Truncated {
            at: self.place_of(self.at()),
            context: context.to_string(),
        }
    }

    fn skip_ws(&mut self) {
        while let Some(&c) = self.b.get(self.pos) {
            if c == b'\n' {
                self.line += 1;
            } else if !c.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
    }

    /// Whether only blank space is left on the current line (or the file ends).
    fn at_line_end(&self) -> bool {
        self.b[self.pos.min(self.b.len())..]
            .iter()
            .find(|&&c| !matches!(c, b' ' | b'\t' | b'\r'))
            .is_none_or(|&c| c == b'\n')
    }

    /// The next whitespace-separated ASCII token and its line.
    fn token(&mut self, context: &str) -> R<(&'a str, usize)> {
        self.skip_ws();
        let start = self.pos;
        let at = self.at();
        while let Some(&c) = self.b.get(self.pos) {
            if c.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        if start == self.pos {
            return Err(self.truncated(context));
        }
        std::str::from_utf8(&self.b[start..self.pos])
            .map(|s| (s, at))
            .map_err(|_| self.syntax(at, format!("{context}: not text")))
    }

    /// The rest of the current line (after skipping blank space), without its end.
    fn line_text(&mut self, context: &str) -> R<(&'a str, usize)> {
        self.skip_ws();
        if self.pos >= self.b.len() {
            return Err(self.truncated(context));
        }
        let at = self.at();
        let start = self.pos;
        while let Some(&c) = self.b.get(self.pos) {
            if c == b'\n' {
                break;
            }
            self.pos += 1;
        }
        let text = std::str::from_utf8(&self.b[start..self.pos])
            .map_err(|_| self.syntax(at, format!("{context}: not text")))?;
        Ok((text.trim_end(), at))
    }

    fn parse<T: std::str::FromStr>(&mut self, context: &str) -> R<(T, usize)> {
        let (t, at) = self.token(context)?;
        t.parse::<T>()
            .map(|v| (v, at))
            .map_err(|_| self.syntax(at, format!("{context}: '{t}' is not a valid number here")))
    }

    fn raw<const N: usize>(&mut self, context: &str) -> R<[u8; N]> {
        let Some(s) = self.b.get(self.pos..self.pos + N) else {
            self.pos = self.b.len();
            return Err(self.truncated(context));
        };
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        self.pos += N;
        if self.big_endian {
            a.reverse();
        }
        Ok(a)
    }

    /// An `int`.
    fn int(&mut self, context: &str) -> R<(i64, usize)> {
        if self.binary {
            let at = self.pos;
            Ok((i32::from_le_bytes(self.raw::<4>(context)?) as i64, at))
        } else {
            self.parse(context)
        }
    }

    /// A `size_t`.
    fn size(&mut self, context: &str) -> R<(u64, usize)> {
        if self.binary {
            let at = self.pos;
            let v = if self.size_t == 4 {
                u32::from_le_bytes(self.raw::<4>(context)?) as u64
            } else {
                u64::from_le_bytes(self.raw::<8>(context)?)
            };
            Ok((v, at))
        } else {
            self.parse(context)
        }
    }

    /// A `double`.
    fn f64(&mut self, context: &str) -> R<(f64, usize)> {
        if self.binary {
            let at = self.pos;
            Ok((f64::from_le_bytes(self.raw::<8>(context)?), at))
        } else {
            self.parse(context)
        }
    }

    /// The section end `$End{name}`.
    fn end(&mut self, name: &str) -> R<()> {
        let context = format!("expected $End{name}");
        let (t, at) = self.token(&context)?;
        if t != format!("$End{name}") {
            return Err(self.syntax(at, format!("expected $End{name}, found '{}'", clip(t))));
        }
        Ok(())
    }

    /// Skip an unknown section to the line after `$End{name}`.
    fn skip_section(&mut self, name: &str, at: usize) -> R<()> {
        let end = format!("$End{name}");
        let rest = &self.b[self.pos..];
        let Some(k) = rest.windows(end.len()).position(|w| w == end.as_bytes()) else {
            return Err(self.syntax(at, format!("section ${name} has no {end}")));
        };
        self.line += rest[..k].iter().filter(|&&c| c == b'\n').count();
        self.pos += k + end.len();
        Ok(())
    }
}

fn clip(t: &str) -> String {
    t.chars().take(40).collect()
}

/// Read a Gmsh MSH 4.1 file (ASCII or binary).
pub fn read(path: &Path) -> Result<MeshFile, ImportError> {
    let bytes = std::fs::read(path).map_err(|e| ImportError::Io {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    parse(path, &bytes)
}

/// Physical tags of each entity `(dim, tag)`.
type Entities = HashMap<(i64, i64), Vec<i64>>;

/// Parse the bytes of an MSH file.
pub(crate) fn parse(path: &Path, bytes: &[u8]) -> Result<MeshFile, ImportError> {
    let mut c = Cur {
        b: bytes,
        pos: 0,
        line: 1,
        path,
        binary: false,
        big_endian: false,
        size_t: 8,
    };
    // $MeshFormat
    c.skip_ws();
    let first = c.at();
    let head = c.token("expected $MeshFormat").ok().map(|(t, _)| t);
    if head != Some("$MeshFormat") {
        return Err(c.syntax(
            first,
            "not a Gmsh MSH file: it does not begin with $MeshFormat",
        ));
    }
    let (version, vat) = c.token("the MSH version")?;
    if version != "4.1" {
        return Err(ImportError::MshVersion {
            at: c.place_of(vat),
            version: clip(version),
        });
    }
    let (file_type, fat) = c.parse::<i64>("the file type")?;
    let (data_size, dat) = c.parse::<i64>("the data size")?;
    match file_type {
        0 => {}
        1 => {
            if data_size != 4 && data_size != 8 {
                return Err(c.syntax(dat, format!("data size {data_size}: expected 8 (or 4)")));
            }
            c.size_t = data_size as usize;
            // the line end, then the int 1 in the file's byte order
            if c.b.get(c.pos) == Some(&b'\r') {
                c.pos += 1;
            }
            if c.b.get(c.pos) == Some(&b'\n') {
                c.pos += 1;
                c.line += 1;
            }
            c.binary = true;
            let at = c.pos;
            let one = c.raw::<4>("the binary format's integer 1")?;
            if i32::from_le_bytes(one) != 1 {
                if i32::from_be_bytes(one) == 1 {
                    c.big_endian = true;
                } else {
                    return Err(c.syntax(
                        at,
                        "binary MSH: the integer after the format line is not 1 in either byte order",
                    ));
                }
            }
        }
        _ => {
            return Err(c.syntax(
                fat,
                format!("file type {file_type}: expected 0 (ASCII) or 1 (binary)"),
            ))
        }
    }
    c.end("MeshFormat")?;

    let mut file = MeshFile::empty(path, Format::Gmsh, c.binary);
    let mut names: HashMap<(i64, i64), String> = HashMap::new();
    let mut entities: Entities = HashMap::new();
    let mut node_sets: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    loop {
        c.skip_ws();
        if c.pos >= c.b.len() {
            break;
        }
        let (t, at) = c.token("a section")?;
        let Some(name) = t.strip_prefix('$') else {
            return Err(c.syntax(
                at,
                format!("expected a section ($Name), found '{}'", clip(t)),
            ));
        };
        let name = name.to_string();
        if c.binary {
            // the header's line end; the binary data follow
            if c.b.get(c.pos) == Some(&b'\r') {
                c.pos += 1;
            }
            if c.b.get(c.pos) == Some(&b'\n') {
                c.pos += 1;
            }
        }
        match name.as_str() {
            "PhysicalNames" => read_names(&mut c, &mut names)?,
            "Entities" => read_entities(&mut c, &mut entities)?,
            "Nodes" => read_nodes(&mut c, &mut file)?,
            "Elements" => read_elements(&mut c, &mut file, &names, &entities, &mut node_sets)?,
            _ if name.starts_with("End") => {
                return Err(c.syntax(at, format!("{} without its section", clip(t))))
            }
            _ => c.skip_section(&name, at)?,
        }
    }
    for v in node_sets.values_mut() {
        v.sort_unstable();
        v.dedup();
    }
    file.node_sets = node_sets;
    Ok(file)
}

fn read_names(c: &mut Cur, names: &mut HashMap<(i64, i64), String>) -> R<()> {
    // always ASCII, even in a binary file
    let binary = c.binary;
    c.binary = false;
    let result = (|| {
        let (n, _) = c.parse::<u64>("the number of physical names")?;
        for _ in 0..n {
            let (dim, _) = c.parse::<i64>("a physical name's dimension")?;
            let (tag, _) = c.parse::<i64>("a physical name's tag")?;
            let (text, at) = c.line_text("a physical name")?;
            let name = text.trim();
            let name = name
                .strip_prefix('"')
                .and_then(|s| s.strip_suffix('"'))
                .ok_or_else(|| {
                    c.syntax(at, format!("physical name {} not in quotes", clip(name)))
                })?;
            if name.is_empty() {
                return Err(c.syntax(at, "empty physical name"));
            }
            names.insert((dim, tag), name.to_string());
        }
        c.end("PhysicalNames")
    })();
    c.binary = binary;
    result
}

fn read_entities(c: &mut Cur, entities: &mut Entities) -> R<()> {
    let mut counts = [0u64; 4];
    for n in counts.iter_mut() {
        *n = c.size("the number of entities")?.0;
    }
    for (dim, &n) in counts.iter().enumerate() {
        for _ in 0..n {
            let (tag, _) = c.int("an entity tag")?;
            let coords = if dim == 0 { 3 } else { 6 };
            for _ in 0..coords {
                c.f64("an entity's coordinates")?;
            }
            let (np, _) = c.size("an entity's number of physical tags")?;
            let mut phys = Vec::new();
            for _ in 0..np {
                phys.push(c.int("a physical tag")?.0);
            }
            if dim > 0 {
                let (nb, _) = c.size("an entity's number of bounding entities")?;
                for _ in 0..nb {
                    c.int("a bounding entity tag")?;
                }
            }
            entities.insert((dim as i64, tag), phys);
        }
    }
    c.end("Entities")
}

fn read_nodes(c: &mut Cur, file: &mut MeshFile) -> R<()> {
    let (blocks, _) = c.size("the number of node blocks")?;
    for _ in 0..4 - 1 {
        c.size("the node counts")?;
    }
    for _ in 0..blocks {
        let (dim, dat) = c.int("a node block's entity dimension")?;
        c.int("a node block's entity tag")?;
        let (parametric, _) = c.int("a node block's parametric flag")?;
        let (n, _) = c.size("a node block's number of nodes")?;
        if !(0..=3).contains(&dim) {
            return Err(c.syntax(dat, format!("node block of entity dimension {dim}")));
        }
        let extra = if parametric != 0 { dim as usize } else { 0 };
        let first = file.nodes.len();
        for _ in 0..n {
            let (id, at) = c.size("a node tag")?;
            file.nodes.push(super::import::FileNode {
                id,
                x: [0.0; 3],
                line: at,
            });
        }
        for k in 0..n as usize {
            let mut x = [0.0; 3];
            for v in x.iter_mut() {
                *v = c.f64("node coordinates")?.0;
            }
            for _ in 0..extra {
                c.f64("parametric node coordinates")?;
            }
            if let Some(node) = file.nodes.get_mut(first + k) {
                node.x = x;
                if !c.binary {
                    node.line = c.line;
                }
            }
        }
    }
    c.end("Nodes")
}

fn read_elements(
    c: &mut Cur,
    file: &mut MeshFile,
    names: &HashMap<(i64, i64), String>,
    entities: &Entities,
    node_sets: &mut BTreeMap<String, Vec<u64>>,
) -> R<()> {
    let (blocks, _) = c.size("the number of element blocks")?;
    for _ in 0..3 {
        c.size("the element counts")?;
    }
    for _ in 0..blocks {
        let (dim, dat) = c.int("an element block's entity dimension")?;
        let (tag, _) = c.int("an element block's entity tag")?;
        let (etype, tat) = c.int("an element block's element type")?;
        let (n, _) = c.size("an element block's number of elements")?;
        let Some((tname, nn, tdim)) = element_type(etype) else {
            return Err(ImportError::UnsupportedElement {
                at: c.place_of(tat),
                kind: format!("type {etype} (no Gmsh element type)"),
                supported: SUPPORTED,
            });
        };
        let solid = solid_shape(etype);
        if solid.is_none() && !matches!(etype, 15 | 1 | 8 | 2 | 9 | 3 | 16) {
            return Err(ImportError::UnsupportedElement {
                at: c.place_of(tat),
                kind: format!("type {etype}, {tname}"),
                supported: SUPPORTED,
            });
        }
        if dim != tdim {
            return Err(c.syntax(
                dat,
                format!("a block of {tname}s in an entity of dimension {dim}"),
            ));
        }
        let groups: Vec<String> = entities
            .get(&(dim, tag))
            .map(|phys| {
                phys.iter()
                    .map(|&p| {
                        names.get(&(dim, p)).cloned().unwrap_or_else(|| {
                            let kind = ["Point", "Line", "Surface", "Volume"][dim as usize];
                            format!("Physical{kind}{p}")
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        for _ in 0..n {
            let (id, at) = c.size("an element tag")?;
            let mut nodes = Vec::with_capacity(nn);
            for k in 0..nn {
                let (tag, tat) = c.size("an element's node tags")?;
                // an ASCII file writes each element on its own line: a short line would take
                // the next element's tags
                if !c.binary && tat != at {
                    return Err(c.syntax(
                        at,
                        format!("element {id}: {k} node tags on its line, a {tname} has {nn}"),
                    ));
                }
                nodes.push(tag);
            }
            if !c.binary && !c.at_line_end() {
                return Err(c.syntax(
                    at,
                    format!(
                        "element {id}: more than {nn} node tags on its line, a {tname} has {nn}"
                    ),
                ));
            }
            for g in &groups {
                node_sets.entry(g.clone()).or_default().extend(&nodes);
            }
            if let Some(shape) = solid {
                let k = file.elements.len();
                for g in &groups {
                    file.element_sets.entry(g.clone()).or_default().push(k);
                }
                file.elements.push(FileElement {
                    id,
                    shape,
                    nodes: gmsh_order(shape).iter().map(|&g| nodes[g]).collect(),
                    line: at,
                });
            } else {
                if matches!(etype, 2 | 9 | 3 | 16) {
                    for g in &groups {
                        file.face_sets
                            .entry(g.clone())
                            .or_default()
                            .push(FileFace::Nodes {
                                nodes: nodes.clone(),
                                line: at,
                            });
                    }
                }
                file.other_elements.push(OtherElement {
                    id,
                    kind: short_name(etype).to_string(),
                    nodes,
                    line: at,
                });
            }
        }
    }
    c.end("Elements")
}

/// What the writers write: the bodies' nodes and, per body, its sets without the prefix.
pub(crate) struct Plan<'a> {
    /// Mesh node numbers written, sorted (file id = number + 1).
    pub nodes: Vec<usize>,
    /// `(body name, group, node sets, face sets)`.
    #[allow(clippy::type_complexity)]
    pub bodies: Vec<(
        &'a str,
        usize,
        Vec<(&'a str, &'a Vec<usize>)>,
        Vec<(&'a str, &'a super::FaceSet)>,
    )>,
}

/// Check the bodies and gather what to write.
pub(crate) fn plan<'a>(
    mesh: &'a Mesh,
    x: &[Vector3<f64>],
    bodies: &'a [(String, usize)],
    path: &Path,
) -> Result<Plan<'a>, ImportError> {
    let err = |message: String| ImportError::Write {
        file: path.to_path_buf(),
        message,
    };
    if x.len() < mesh.n_nodes() {
        return Err(err(format!(
            "{} coordinates for {} nodes",
            x.len(),
            mesh.n_nodes()
        )));
    }
    let mut used = vec![false; mesh.n_nodes()];
    let mut out = Vec::new();
    for (name, g) in bodies {
        if name.is_empty()
            || name
                .chars()
                .any(|c| c.is_whitespace() || c == '"' || c == ',')
        {
            return Err(err(format!(
                "body name '{name}': empty, or with blank space, quotes or commas"
            )));
        }
        let Some(group) = mesh.groups.get(*g) else {
            return Err(err(format!("body '{name}': no group {g}")));
        };
        if solid_type(group.shape).is_none() {
            return Err(err(format!(
                "body '{name}': group {g} holds {} elements; only solid bodies are written",
                group.shape.name()
            )));
        }
        for &n in &group.nodes {
            used[n] = true;
        }
        let prefix = format!("{name}.");
        let node_sets: Vec<(&str, &Vec<usize>)> = mesh
            .node_sets
            .iter()
            .filter_map(|(k, v)| Some((k.strip_prefix(&prefix)?, v)))
            .filter(|(_, v)| !v.is_empty())
            .collect();
        let face_sets: Vec<(&str, &super::FaceSet)> = mesh
            .face_sets
            .iter()
            .filter_map(|(k, v)| Some((k.strip_prefix(&prefix)?, v)))
            .filter(|(_, v)| !v.is_empty())
            .collect();
        let set_names = node_sets
            .iter()
            .map(|(s, _)| *s)
            .chain(face_sets.iter().map(|(s, _)| *s));
        for set in set_names {
            if set.is_empty()
                || set
                    .chars()
                    .any(|c| c.is_whitespace() || c == '"' || c == ',')
            {
                return Err(err(format!(
                    "set '{name}.{set}': a name with blank space, quotes or commas"
                )));
            }
        }
        out.push((name.as_str(), *g, node_sets, face_sets));
    }
    // every node of a set must be a body node
    for (name, _, ns, fs) in &out {
        for (set, v) in ns {
            if let Some(n) = v.iter().find(|&&n| n >= used.len() || !used[n]) {
                return Err(err(format!(
                    "node set '{name}.{set}' holds node {n}, which no body written has"
                )));
            }
        }
        for (set, f) in fs {
            if let Some(n) = f.all_nodes().iter().find(|&&n| n >= used.len() || !used[n]) {
                return Err(err(format!(
                    "face set '{name}.{set}' holds node {n}, which no body written has"
                )));
            }
        }
    }
    let nodes: Vec<usize> = (0..mesh.n_nodes()).filter(|&n| used[n]).collect();
    if let Some(&n) = nodes.iter().find(|&&n| !x[n].iter().all(|c| c.is_finite())) {
        return Err(err(format!("node {n}: coordinates {:?} not finite", x[n])));
    }
    Ok(Plan { nodes, bodies: out })
}

/// Output helper: ASCII text or little-endian binary values.
struct Out {
    s: Vec<u8>,
    binary: bool,
    big_endian: bool,
}

impl Out {
    fn text(&mut self, t: &str) {
        self.s.extend_from_slice(t.as_bytes());
    }
    /// A value: its text and a space in ASCII, its bytes (`le` or `be`) in binary.
    fn value<const N: usize>(&mut self, ascii: std::fmt::Arguments, le: [u8; N], be: [u8; N]) {
        if !self.binary {
            self.s.extend_from_slice(format!("{ascii} ").as_bytes());
        } else if self.big_endian {
            self.s.extend_from_slice(&be);
        } else {
            self.s.extend_from_slice(&le);
        }
    }
    fn int(&mut self, v: i32) {
        self.value(format_args!("{v}"), v.to_le_bytes(), v.to_be_bytes());
    }
    fn size(&mut self, v: usize) {
        let v = v as u64;
        self.value(format_args!("{v}"), v.to_le_bytes(), v.to_be_bytes());
    }
    fn f64(&mut self, v: f64) {
        // `{:?}`: the shortest text that reads back to the same double
        self.value(format_args!("{v:?}"), v.to_le_bytes(), v.to_be_bytes());
    }
    /// End of an ASCII line (nothing in binary).
    fn nl(&mut self) {
        if !self.binary {
            if self.s.last() == Some(&b' ') {
                self.s.pop();
            }
            self.s.push(b'\n');
        }
    }
}

/// Write `bodies` (name, solid group) of `mesh` at coordinates `x` as MSH 4.1, ASCII or binary,
/// with each body's sets `NAME.SET` as physical groups `SET` (see the module documentation).
pub fn write(
    mesh: &Mesh,
    x: &[Vector3<f64>],
    bodies: &[(String, usize)],
    path: &Path,
    binary: bool,
) -> Result<(), ImportError> {
    write_msh(mesh, x, bodies, path, binary, false)
}

/// [`write`], binary files in either byte order.
fn write_msh(
    mesh: &Mesh,
    x: &[Vector3<f64>],
    bodies: &[(String, usize)],
    path: &Path,
    binary: bool,
    big_endian: bool,
) -> Result<(), ImportError> {
    let plan = plan(mesh, x, bodies, path)?;
    let mut o = Out {
        s: Vec::new(),
        binary,
        big_endian,
    };
    o.text(&format!("$MeshFormat\n4.1 {} 8\n", u8::from(binary)));
    if binary {
        o.int(1);
        o.text("\n");
    }
    o.text("$EndMeshFormat\n");
    // physical groups: volumes by body, surfaces and points by set name
    let mut surf_tags: BTreeMap<&str, i32> = BTreeMap::new();
    let mut point_tags: BTreeMap<&str, i32> = BTreeMap::new();
    for (_, _, ns, fs) in &plan.bodies {
        for (s, _) in fs {
            let n = surf_tags.len() as i32 + 1;
            surf_tags.entry(s).or_insert(n);
        }
        for (s, _) in ns {
            let n = point_tags.len() as i32 + 1;
            point_tags.entry(s).or_insert(n);
        }
    }
    o.text(&format!(
        "$PhysicalNames\n{}\n",
        plan.bodies.len() + surf_tags.len() + point_tags.len()
    ));
    for (s, t) in &point_tags {
        o.text(&format!("0 {t} \"{s}\"\n"));
    }
    for (s, t) in &surf_tags {
        o.text(&format!("2 {t} \"{s}\"\n"));
    }
    for (b, (name, ..)) in plan.bodies.iter().enumerate() {
        o.text(&format!("3 {} \"{name}\"\n", b + 1));
    }
    o.text("$EndPhysicalNames\n");
    // entities
    let bbox = |nodes: &mut dyn Iterator<Item = usize>| {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for n in nodes {
            for c in 0..3 {
                lo[c] = lo[c].min(x[n][c]);
                hi[c] = hi[c].max(x[n][c]);
            }
        }
        if lo[0] > hi[0] {
            ([0.0; 3], [0.0; 3])
        } else {
            (lo, hi)
        }
    };
    /// An element: its Gmsh type and its nodes in fricsens' order.
    type Element<'e> = (i32, &'e [usize]);
    /// An entity and its elements.
    struct Entity<'e> {
        dim: i32,
        tag: i32,
        phys: i32,
        elements: Vec<Element<'e>>,
    }
    let mut points: Vec<Entity> = Vec::new();
    let mut surfaces: Vec<Entity> = Vec::new();
    let mut volumes: Vec<Entity> = Vec::new();
    for (b, (_, g, ns, fs)) in plan.bodies.iter().enumerate() {
        let group = &mesh.groups[*g];
        // plan() wrote only solid groups
        let etype = solid_type(group.shape).unwrap_or(0);
        volumes.push(Entity {
            dim: 3,
            tag: b as i32 + 1,
            phys: b as i32 + 1,
            elements: (0..group.len())
                .map(|k| (etype, group.element(k)))
                .collect(),
        });
        for (s, f) in fs {
            surfaces.push(Entity {
                dim: 2,
                tag: surfaces.len() as i32 + 1,
                phys: surf_tags[s],
                elements: f.iter().map(|f| (face_type(f.family), f.nodes)).collect(),
            });
        }
        for (s, v) in ns {
            points.push(Entity {
                dim: 0,
                tag: points.len() as i32 + 1,
                phys: point_tags[s],
                elements: v.chunks(1).map(|n| (15, n)).collect(),
            });
        }
    }
    o.text("$Entities\n");
    for n in [points.len(), 0, surfaces.len(), volumes.len()] {
        o.size(n);
    }
    o.nl();
    for e in points.iter().chain(&surfaces).chain(&volumes) {
        o.int(e.tag);
        let (lo, hi) = bbox(&mut e.elements.iter().flat_map(|el| el.1.iter().copied()));
        for v in lo {
            o.f64(v);
        }
        if e.dim > 0 {
            for v in hi {
                o.f64(v);
            }
        }
        o.size(1);
        o.int(e.phys);
        if e.dim > 0 {
            o.size(0);
        }
        o.nl();
    }
    if binary {
        o.text("\n");
    }
    o.text("$EndEntities\n");
    // nodes: each in the volume block of the first body that has it
    let mut owner = vec![usize::MAX; mesh.n_nodes()];
    let mut block_nodes: Vec<Vec<usize>> = vec![Vec::new(); plan.bodies.len()];
    for (b, (_, g, ..)) in plan.bodies.iter().enumerate() {
        for &n in &mesh.groups[*g].nodes {
            if owner[n] == usize::MAX {
                owner[n] = b;
                block_nodes[b].push(n);
            }
        }
    }
    for v in block_nodes.iter_mut() {
        v.sort_unstable();
    }
    o.text("$Nodes\n");
    let (min, max) = (
        plan.nodes.first().map_or(0, |n| n + 1),
        plan.nodes.last().map_or(0, |n| n + 1),
    );
    for v in [plan.bodies.len(), plan.nodes.len(), min, max] {
        o.size(v);
    }
    o.nl();
    for (b, nodes) in block_nodes.iter().enumerate() {
        o.int(3);
        o.int(b as i32 + 1);
        o.int(0);
        o.size(nodes.len());
        o.nl();
        for &n in nodes {
            o.size(n + 1);
            o.nl();
        }
        for &n in nodes {
            for &v in x[n].iter() {
                o.f64(v);
            }
            o.nl();
        }
    }
    if binary {
        o.text("\n");
    }
    o.text("$EndNodes\n");
    // elements
    // the solids first, so that they are numbered 1.. as by the Abaqus writer; one block per
    // run of elements of one type in an entity (a wedge's face set mixes triangles and
    // quadrangles), so that the elements keep their order
    let all: Vec<&Entity> = volumes.iter().chain(&surfaces).chain(&points).collect();
    let mut blocks: Vec<(&Entity, i32, &[Element])> = Vec::new();
    for e in &all {
        for run in e.elements.chunk_by(|a, b| a.0 == b.0) {
            blocks.push((e, run[0].0, run));
        }
    }
    let total: usize = all.iter().map(|e| e.elements.len()).sum();
    o.text("$Elements\n");
    for v in [blocks.len(), total, usize::from(total > 0), total] {
        o.size(v);
    }
    o.nl();
    let mut id = 0usize;
    for (e, etype, run) in blocks {
        o.int(e.dim);
        o.int(e.tag);
        o.int(etype);
        o.size(run.len());
        o.nl();
        // Gmsh node j of a solid is fricsens node order^-1 (j): write node k at order[k]
        let order = solid_shape(i64::from(etype)).map(gmsh_order);
        let mut nodes = Vec::new();
        for (_, el) in run {
            id += 1;
            o.size(id);
            nodes.clear();
            nodes.extend_from_slice(el);
            if let Some(order) = order {
                for (k, &g) in order.iter().enumerate() {
                    nodes[g] = el[k];
                }
            }
            for &n in &nodes {
                o.size(n + 1);
            }
            o.nl();
        }
    }
    if binary {
        o.text("\n");
    }
    o.text("$EndElements\n");
    std::fs::write(path, &o.s).map_err(|e| ImportError::Write {
        file: path.to_path_buf(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Axis, BlockSpec};

    /// Both byte orders of a binary file read to the same nodes, elements and sets.
    #[test]
    fn big_endian_binary_reads_like_little_endian() {
        let mut m = Mesh::default();
        m.add_block(BlockSpec {
            element: crate::element::Shape::Hex8,
            name: "b".into(),
            origin: [0.1, 0.2, 0.3],
            x: Axis::uniform(1.3, 2),
            y: Axis::uniform(0.7, 1),
            z: Axis::uniform(0.9, 2),
        })
        .unwrap();
        let x = m.coordinates::<f64>(&m.block_geometry());
        let dir = std::env::temp_dir().join(format!("fricsens-gmsh-endian-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let bodies = vec![("b".to_string(), 0)];
        let (le, be) = (dir.join("le.msh"), dir.join("be.msh"));
        write_msh(&m, &x, &bodies, &le, true, false).unwrap();
        write_msh(&m, &x, &bodies, &be, true, true).unwrap();
        let (a, b) = (read(&le).unwrap(), read(&be).unwrap());
        assert_ne!(std::fs::read(&le).unwrap(), std::fs::read(&be).unwrap());
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(a.nodes.len(), 3 * 2 * 3);
        assert_eq!(a.nodes, b.nodes);
        assert_eq!(a.elements, b.elements);
        assert_eq!(a.other_elements, b.other_elements);
        assert_eq!(a.element_sets, b.element_sets);
        assert_eq!(a.node_sets, b.node_sets);
        assert_eq!(a.face_sets, b.face_sets);
        // the sixth node (tag 6) is x-index 2, y-index 1, z-index 0
        let n = a.nodes.iter().find(|n| n.id == 6).unwrap();
        assert_eq!(n.x, [x[5][0], x[5][1], x[5][2]]);
        assert_eq!(n.x[0], 0.1 + 1.3);
    }

    #[test]
    fn every_supported_type_has_its_node_count() {
        for (t, n) in [(1, 2), (8, 3), (2, 3), (9, 6), (3, 4), (16, 8), (15, 1)] {
            assert_eq!(element_type(t).map(|e| e.1), Some(n));
        }
        for shape in Shape::SOLIDS {
            let t = solid_type(shape).unwrap();
            assert_eq!(solid_shape(i64::from(t)), Some(shape));
            assert_eq!(
                element_type(i64::from(t)).map(|e| e.1),
                Some(shape.n_nodes())
            );
        }
        assert!(element_type(0).is_none() && element_type(20).is_none());
    }

    /// Gmsh's reference nodes of types 4, 11, 5, 17, 6, 18 as
    /// `gmsh.model.mesh.getElementProperties` lists them (gmsh 4.15.2; the manual's
    /// node-ordering figures show the same): tetrahedra in `(u, v, w)` with corner 0 at the
    /// origin, hexahedra in `[-1, 1]^3`, prisms a triangle `(u, v)` swept along
    /// `w in [-1, 1]`, which are fricsens' natural coordinates of each shape. Permuted by
    /// [`gmsh_order`], they must be fricsens' natural nodes.
    #[test]
    fn gmsh_orders_put_gmsh_reference_nodes_at_fricsens_natural_nodes() {
        const TET10: [[f64; 3]; 10] = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.5, 0.0, 0.0],
            [0.5, 0.5, 0.0],
            [0.0, 0.5, 0.0],
            [0.0, 0.0, 0.5],
            [0.0, 0.5, 0.5],
            [0.5, 0.0, 0.5],
        ];
        const HEX20: [[f64; 3]; 20] = [
            [-1.0, -1.0, -1.0],
            [1.0, -1.0, -1.0],
            [1.0, 1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [1.0, 1.0, 1.0],
            [-1.0, 1.0, 1.0],
            [0.0, -1.0, -1.0],
            [-1.0, 0.0, -1.0],
            [-1.0, -1.0, 0.0],
            [1.0, 0.0, -1.0],
            [1.0, -1.0, 0.0],
            [0.0, 1.0, -1.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [0.0, -1.0, 1.0],
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        const PRISM15: [[f64; 3]; 15] = [
            [0.0, 0.0, -1.0],
            [1.0, 0.0, -1.0],
            [0.0, 1.0, -1.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [0.5, 0.0, -1.0],
            [0.0, 0.5, -1.0],
            [0.0, 0.0, 0.0],
            [0.5, 0.5, -1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5, 0.0, 1.0],
            [0.0, 0.5, 1.0],
            [0.5, 0.5, 1.0],
        ];
        // the linear types are the first nodes of the quadratic ones
        for (shape, gmsh) in [
            (Shape::Tet4, &TET10[..4]),
            (Shape::Tet10, &TET10[..]),
            (Shape::Hex8, &HEX20[..8]),
            (Shape::Hex20, &HEX20[..]),
            (Shape::Wedge6, &PRISM15[..6]),
            (Shape::Wedge15, &PRISM15[..]),
        ] {
            let order = gmsh_order(shape);
            assert_eq!(order.len(), shape.n_nodes());
            let mut sorted = order.to_vec();
            sorted.sort_unstable();
            assert_eq!(
                sorted,
                (0..shape.n_nodes()).collect::<Vec<_>>(),
                "{shape:?}"
            );
            for (k, xi) in shape.natural_nodes().iter().enumerate() {
                assert_eq!(gmsh[order[k]], *xi, "{shape:?} node {k}");
            }
        }
    }
}
