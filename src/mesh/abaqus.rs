//! Abaqus/CalculiX `.inp` meshes: reader and writer (see [`super::import`] for how a read
//! file enters a mesh).
//!
//! The reader takes a flat input file: `*NODE` (with `NSET=`), `*ELEMENT` (`TYPE=`, `ELSET=`),
//! `*NSET` and `*ELSET` (with `GENERATE`, and with names of sets defined before among the
//! members; `*NSET, ELSET=` takes an element set's nodes), `*SURFACE` (`TYPE=ELEMENT`, the
//! default: lines `element or element set, Sn`; `TYPE=NODE`: a node set) and `*INCLUDE,
//! INPUT=` (a path relative to the including file; includes nest, a cycle is an error).
//! Keywords and parameters are case-insensitive, `**` starts a comment, and a line ending
//! with a comma continues on the next. Any other keyword (`*MATERIAL`, `*STEP`, `*BOUNDARY`,
//! `*HEADING`, ...) is skipped with its data lines. `*PART`, `*INSTANCE` and `*ASSEMBLY`
//! are refused with a typed error: write a flat input file (in Abaqus/CAE, untick "Use
//! parts and assemblies in input files"; Gmsh and CalculiX files are flat).
//!
//! Elements: the solids `C3D8` (hex8), `C3D20` (hex20), `C3D4` (tet4), `C3D10` (tet10), `C3D6`
//! (wedge6) and `C3D15` (wedge15), and their variants (letters after the name: `C3D8R`,
//! `C3D8I`, `C3D8H`, `C3D20R`, `C3D20RH`, `C3D10M`, `C3D10H`, `C3D4H`, `C3D6H`, ...; not the
//! variable-node `C3D15V`), node order as fricsens' (Abaqus numbers as fricsens does). Plane,
//! membrane, shell and surface elements with 3, 4, 6 or 8 nodes (`CPS4`, `CPE4`, `CAX4`, `S4`,
//! `S4R`, `M3D4`, `SFM3D4`, `R3D4`, `CPS8`, `S8R`, `CPS6`, `STRI65`, their 3-node and reduced
//! variants; Gmsh writes a physical surface as `CPS3`, `CPS4`, `CPS6` or `CPS8` elements) only
//! define sets: an element set of them is a face set. Truss and beam elements (`T3D2`, `B31`,
//! `T3D3`, `B32`, ...) likewise: an element set of them is a node set. Any other type
//! (`C3D27`, `C3D5`, `C3D15V`, ...) is [`ImportError::UnsupportedElement`].
//!
//! Element-based surfaces name sides `S1`..`S6`, numbered per shape as the Abaqus and CalculiX
//! manuals number them ([`super::import`] maps each to its face).
//!
//! Set names are case-insensitive, as in Abaqus: the reader keeps a name's first spelling
//! (`*NSET, NSET=Top` then `*NSET, NSET=TOP` is one set `Top`), and
//! [`super::import::MeshFile::add_to`] matches the element set name case-insensitively.
//!
//! The writer writes `*NODE`, one `*ELEMENT, TYPE=C3D.., ELSET=BODY` per body (its shape's
//! type: `C3D8`, `C3D20`, `C3D4`, `C3D10`, `C3D6`, `C3D15`; at most 16 entries a data line, an
//! element of more nodes continued on the next line), a `*NSET` per
//! node set and a `*SURFACE, TYPE=ELEMENT` per face set, its lines `element id, Sn` (no helper
//! element sets, which would read back as sets of their own). The sets of each body
//! are written without the `BODY.` prefix (sets of one name in several bodies are written as
//! one), so that reading back with prefix `BODY` and element set `BODY` gives the same names.

use super::import::{
    side_of_face, FileElement, FileFace, FileNode, Format, ImportError, MeshFile, OtherElement,
    Place,
};
use super::Mesh;
use crate::element::Shape;
use nalgebra::Vector3;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

const SUPPORTED: &str = "C3D8, C3D20, C3D4, C3D10, C3D6, C3D15 and their variants (C3D8R, C3D8I, C3D20R, C3D10M, C3D4H, ...) as solids; 3-, 4-, 6- and 8-node plane, membrane, shell and surface elements (CPS4, S4R, M3D4, SFM3D4, R3D4, CPS6, CPS8, S8R, ...) and 2- and 3-node trusses and beams (T3D2, B31, T3D3, B32) for sets";

/// How an element type enters: a solid of a shape, or, with its node count, a set-only
/// surface or line element.
enum Kind {
    Solid(Shape),
    Surface(usize),
    Line(usize),
}

/// The Abaqus solid type of each shape (the writer's), and the reader's base names.
const SOLID_TYPES: [(&str, Shape); 6] = [
    ("C3D10", Shape::Tet10),
    ("C3D15", Shape::Wedge15),
    ("C3D20", Shape::Hex20),
    ("C3D4", Shape::Tet4),
    ("C3D6", Shape::Wedge6),
    ("C3D8", Shape::Hex8),
];

/// The Abaqus type the writer gives a solid shape (`None` for a discrete one).
pub(crate) fn abaqus_type(shape: Shape) -> Option<&'static str> {
    SOLID_TYPES
        .iter()
        .find(|(_, s)| *s == shape)
        .map(|(name, _)| *name)
}

fn kind(t: &str) -> Option<Kind> {
    let t = t.to_ascii_uppercase();
    for (base, shape) in SOLID_TYPES {
        if let Some(rest) = t.strip_prefix(base) {
            // C3D8R, C3D8I, C3D20RH, C3D10M, C3D4H, C3D6T, ...: letters only after the name
            // (not C3D15V, whose node count varies)
            let variant = rest.chars().all(|c| c.is_ascii_alphabetic()) && !rest.contains('V');
            return variant.then_some(Kind::Solid(shape));
        }
    }
    const SURF8: [&str; 16] = [
        "CPS8", "CPS8R", "CPE8", "CPE8R", "CPE8H", "CPE8RH", "CAX8", "CAX8R", "CAX8H", "CAX8RH",
        "S8R", "S8R5", "M3D8", "M3D8R", "SFM3D8", "SFM3D8R",
    ];
    const SURF6: [&str; 10] = [
        "CPS6", "CPS6M", "CPE6", "CPE6M", "CPE6H", "CAX6", "CAX6M", "STRI65", "M3D6", "SFM3D6",
    ];
    const SURF4: [&str; 16] = [
        "CPS4", "CPS4R", "CPS4I", "CPE4", "CPE4R", "CPE4I", "CPE4H", "CAX4", "CAX4R", "S4", "S4R",
        "M3D4", "M3D4R", "SFM3D4", "SFM3D4R", "R3D4",
    ];
    const SURF3: [&str; 9] = [
        "CPS3", "CPE3", "CAX3", "S3", "S3R", "M3D3", "SFM3D3", "R3D3", "STRI3",
    ];
    const LINE2: [&str; 6] = ["T3D2", "T2D2", "B31", "B21", "B31H", "B21H"];
    const LINE3: [&str; 6] = ["T3D3", "T2D3", "B32", "B22", "B32H", "B22H"];
    let t = t.as_str();
    if SURF8.contains(&t) {
        Some(Kind::Surface(8))
    } else if SURF6.contains(&t) {
        Some(Kind::Surface(6))
    } else if SURF4.contains(&t) {
        Some(Kind::Surface(4))
    } else if SURF3.contains(&t) {
        Some(Kind::Surface(3))
    } else if LINE2.contains(&t) {
        Some(Kind::Line(2))
    } else if LINE3.contains(&t) {
        Some(Kind::Line(3))
    } else {
        None
    }
}

/// One line of the flattened input (includes read in place).
struct Line {
    text: String,
    /// Global line number (see [`super::import::LineMap`]).
    at: usize,
}

type R<T> = Result<T, ImportError>;

/// Read an Abaqus/CalculiX input file.
pub fn read(path: &Path) -> Result<MeshFile, ImportError> {
    let mut file = MeshFile::empty(path, Format::Abaqus, false);
    file.lines.segments.clear();
    let mut lines = Vec::new();
    let mut stack = Vec::new();
    flatten(path, None, &mut file, &mut lines, &mut stack)?;
    Reader::new(&mut file).run(&lines)?;
    Ok(file)
}

/// Read `path`'s lines (and those of its includes, in place) into `lines`.
fn flatten(
    path: &Path,
    from: Option<Place>,
    file: &mut MeshFile,
    lines: &mut Vec<Line>,
    stack: &mut Vec<PathBuf>,
) -> R<()> {
    let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    if stack.contains(&canonical) {
        let at = from.unwrap_or_else(|| Place::line(path, 0));
        return Err(ImportError::IncludeCycle {
            at,
            target: path.to_path_buf(),
        });
    }
    if stack.len() > 64 {
        let at = from.unwrap_or_else(|| Place::line(path, 0));
        return Err(ImportError::Unsupported {
            at,
            what: "more than 64 nested *INCLUDEs".into(),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| ImportError::Io {
        file: path.to_path_buf(),
        message: match &from {
            Some(p) => format!("{e} (included at {p})"),
            None => e.to_string(),
        },
    })?;
    let text = String::from_utf8_lossy(&bytes);
    if text.contains('\0') {
        return Err(ImportError::Syntax {
            at: Place::line(
                path,
                1 + text[..text.find('\0').unwrap_or(0)].lines().count(),
            ),
            message: "not an Abaqus input file: binary data".into(),
        });
    }
    let index = file.lines.files.len();
    if stack.is_empty() {
        file.lines.files.clear();
    }
    let index = if stack.is_empty() { 0 } else { index };
    file.lines.files.push(path.to_path_buf());
    stack.push(canonical);
    let mut next = lines.len() + 1;
    file.lines.segments.push((next, index, 1));
    for (k, raw) in text.lines().enumerate() {
        let local = k + 1;
        let trimmed = raw.trim();
        let upper = trimmed.to_ascii_uppercase();
        if upper.starts_with("*INCLUDE") && !upper.starts_with("**") {
            let here = Place::line(path, local);
            let target = params(trimmed)
                .into_iter()
                .find(|(k, _)| k == "INPUT")
                .map(|(_, v)| v)
                .filter(|v| !v.is_empty())
                .ok_or_else(|| ImportError::Syntax {
                    at: here.clone(),
                    message: "*INCLUDE without INPUT=".into(),
                })?;
            let target = path.parent().unwrap_or(Path::new("")).join(target);
            lines.push(Line {
                text: "**".into(),
                at: next,
            });
            flatten(&target, Some(here), file, lines, stack)?;
            next = lines.len() + 1;
            file.lines.segments.push((next, index, local + 1));
            continue;
        }
        lines.push(Line {
            text: raw.to_string(),
            at: next,
        });
        next += 1;
    }
    stack.pop();
    Ok(())
}

/// The parameters of a keyword line, keys upper case, values as written (unquoted).
fn params(line: &str) -> Vec<(String, String)> {
    line.split(',')
        .skip(1)
        .filter(|p| !p.trim().is_empty())
        .map(|p| match p.split_once('=') {
            Some((k, v)) => (
                k.trim().to_ascii_uppercase(),
                v.trim().trim_matches('"').to_string(),
            ),
            None => (p.trim().to_ascii_uppercase(), String::new()),
        })
        .collect()
}

/// Parse a number as Abaqus writes it (Fortran `D` exponents too).
fn number(t: &str) -> Option<f64> {
    let t = t.trim();
    t.parse::<f64>()
        .ok()
        .or_else(|| t.replace(['d', 'D'], "e").parse::<f64>().ok())
}

struct Reader<'f> {
    file: &'f mut MeshFile,
    /// Upper-case name -> the first spelling.
    spelling: HashMap<String, String>,
    nsets: BTreeMap<String, Vec<(u64, usize)>>,
    elsets: BTreeMap<String, Vec<(u64, usize)>>,
    /// Element id -> node ids, for `*NSET, ELSET=`.
    element_nodes: HashMap<u64, (usize, bool)>,
}

impl<'f> Reader<'f> {
    fn new(file: &'f mut MeshFile) -> Self {
        Reader {
            file,
            spelling: HashMap::new(),
            nsets: BTreeMap::new(),
            elsets: BTreeMap::new(),
            element_nodes: HashMap::new(),
        }
    }

    fn at(&self, line: usize) -> Place {
        self.file.place(line)
    }

    fn syntax(&self, line: usize, message: impl Into<String>) -> ImportError {
        ImportError::Syntax {
            at: self.at(line),
            message: message.into(),
        }
    }

    fn name(&mut self, name: &str) -> String {
        self.spelling
            .entry(name.to_ascii_uppercase())
            .or_insert_with(|| name.to_string())
            .clone()
    }

    /// The value of parameter `key`, a set name.
    fn set_param(&mut self, p: &[(String, String)], key: &str, line: usize) -> R<Option<String>> {
        match p.iter().find(|(k, _)| k == key) {
            None => Ok(None),
            Some((_, v)) if v.is_empty() => {
                Err(self.syntax(line, format!("{key}= without a name")))
            }
            Some((_, v)) => Ok(Some(self.name(v))),
        }
    }

    fn run(mut self, lines: &[Line]) -> R<()> {
        // logical lines: comments and blanks dropped, continuations joined
        let mut logical: Vec<(String, usize)> = Vec::new();
        let mut open = false;
        for l in lines {
            let t = l.text.trim();
            if t.is_empty() || t.starts_with("**") {
                continue;
            }
            let keyword = t.starts_with('*');
            match logical.last_mut() {
                Some(last) if open && !keyword => {
                    last.0.push_str(t);
                }
                _ => logical.push((t.to_string(), l.at)),
            }
            open = t.ends_with(',');
        }
        let mut k = 0;
        while k < logical.len() {
            let (head, at) = &logical[k];
            k += 1;
            let data_end = logical[k..]
                .iter()
                .position(|(t, _)| t.starts_with('*'))
                .map_or(logical.len(), |p| k + p);
            let data = &logical[k..data_end];
            k = data_end;
            if !head.starts_with('*') {
                return Err(self.syntax(*at, "data line before any keyword"));
            }
            let keyword = head[1..]
                .split(',')
                .next()
                .unwrap_or("")
                .trim()
                .to_ascii_uppercase();
            let keyword: String = keyword.split_whitespace().collect::<Vec<_>>().join(" ");
            let p = params(head);
            match keyword.as_str() {
                "NODE" => self.nodes(&p, data, *at)?,
                "ELEMENT" => self.elements(&p, data, *at)?,
                "NSET" => self.nset(&p, data, *at)?,
                "ELSET" => self.elset(&p, data, *at)?,
                "SURFACE" => self.surface(&p, data, *at)?,
                "PART" | "INSTANCE" | "ASSEMBLY" | "END PART" | "END INSTANCE"
                | "END ASSEMBLY" => {
                    return Err(ImportError::Unsupported {
                        at: self.at(*at),
                        what: format!("*{keyword}: parts, instances and assemblies are not read; write a flat input file (Abaqus/CAE: untick \"Use parts and assemblies in input files\" in the model attributes)"),
                    })
                }
                _ => {}
            }
        }
        self.finish()
    }

    fn tokens(text: &str) -> Vec<&str> {
        let v: Vec<&str> = text.split(',').map(str::trim).collect();
        // a trailing comma leaves an empty last token
        match v.split_last() {
            Some((&"", rest)) => rest.to_vec(),
            _ => v,
        }
    }

    fn int(&self, t: &str, line: usize, what: &str) -> R<u64> {
        t.parse::<u64>().map_err(|_| {
            self.syntax(
                line,
                format!("{what}: '{}' is not a positive integer", clip(t)),
            )
        })
    }

    fn nodes(&mut self, p: &[(String, String)], data: &[(String, usize)], _at: usize) -> R<()> {
        let nset = self.set_param(p, "NSET", _at)?;
        for (text, line) in data {
            let t = Self::tokens(text);
            // id, x[, y[, z]] and up to three normal components (ignored)
            if t.len() < 2 || t.len() > 7 {
                return Err(self.syntax(
                    *line,
                    format!("*NODE: expected 'id, x, y, z', found {} values", t.len()),
                ));
            }
            let id = self.int(t[0], *line, "*NODE: node id")?;
            let mut x = [0.0; 3];
            for (c, v) in t[1..].iter().take(3).enumerate() {
                x[c] = if v.is_empty() {
                    0.0
                } else {
                    number(v).ok_or_else(|| {
                        self.syntax(
                            *line,
                            format!("node {id}: coordinate '{}' is not a number", clip(v)),
                        )
                    })?
                };
            }
            self.file.nodes.push(FileNode { id, x, line: *line });
            if let Some(s) = &nset {
                self.nsets.entry(s.clone()).or_default().push((id, *line));
            }
        }
        Ok(())
    }

    fn elements(&mut self, p: &[(String, String)], data: &[(String, usize)], at: usize) -> R<()> {
        let Some((_, etype)) = p.iter().find(|(k, _)| k == "TYPE") else {
            return Err(self.syntax(at, "*ELEMENT without TYPE="));
        };
        let etype = etype.to_ascii_uppercase();
        let Some(kind) = kind(&etype) else {
            return Err(ImportError::UnsupportedElement {
                at: self.at(at),
                kind: format!("type {}", clip(&etype)),
                supported: SUPPORTED,
            });
        };
        let nn = match kind {
            Kind::Solid(shape) => shape.n_nodes(),
            Kind::Surface(n) | Kind::Line(n) => n,
        };
        let elset = self.set_param(p, "ELSET", at)?;
        for (text, line) in data {
            let t = Self::tokens(text);
            if t.len() != nn + 1 {
                return Err(self.syntax(
                    *line,
                    format!(
                        "*ELEMENT, TYPE={etype}: expected an id and {nn} nodes, found {} values",
                        t.len()
                    ),
                ));
            }
            let id = self.int(t[0], *line, "*ELEMENT: element id")?;
            let mut nodes = Vec::with_capacity(nn);
            for v in &t[1..] {
                nodes.push(self.int(v, *line, &format!("element {id}: node id"))?);
            }
            match kind {
                Kind::Solid(shape) => {
                    self.element_nodes
                        .insert(id, (self.file.elements.len(), true));
                    self.file.elements.push(FileElement {
                        id,
                        shape,
                        nodes,
                        line: *line,
                    });
                }
                Kind::Surface(_) | Kind::Line(_) => {
                    self.element_nodes
                        .insert(id, (self.file.other_elements.len(), false));
                    self.file.other_elements.push(OtherElement {
                        id,
                        kind: etype.clone(),
                        nodes,
                        line: *line,
                    });
                }
            }
            if let Some(s) = &elset {
                self.elsets.entry(s.clone()).or_default().push((id, *line));
            }
        }
        Ok(())
    }

    /// Members of a set's data lines: ids, `GENERATE` triples, names of sets in `sets`.
    fn members(
        &self,
        generate: bool,
        data: &[(String, usize)],
        sets: &BTreeMap<String, Vec<(u64, usize)>>,
        what: &str,
        defined: usize,
    ) -> R<Vec<(u64, usize)>> {
        let mut out = Vec::new();
        for (text, line) in data {
            let t = Self::tokens(text);
            if generate {
                if t.len() < 2 || t.len() > 3 {
                    return Err(self.syntax(
                        *line,
                        format!("{what}, GENERATE: expected 'first, last, step'"),
                    ));
                }
                let a = self.int(t[0], *line, "GENERATE: first")?;
                let b = self.int(t[1], *line, "GENERATE: last")?;
                let s = match t.get(2) {
                    Some(s) => self.int(s, *line, "GENERATE: step")?,
                    None => 1,
                };
                if s == 0 || b < a {
                    return Err(self.syntax(
                        *line,
                        format!("{what}, GENERATE: needs first <= last and a positive step"),
                    ));
                }
                // every member must be defined before: no more members than definitions
                if (b - a) / s >= defined as u64 {
                    return Err(self.syntax(
                        *line,
                        format!("{what}, GENERATE: {a} to {b} by {s} names more members than the {defined} defined before"),
                    ));
                }
                let mut v = a;
                while v <= b {
                    out.push((v, *line));
                    match v.checked_add(s) {
                        Some(n) => v = n,
                        None => break,
                    }
                }
                continue;
            }
            for v in t {
                if v.is_empty() {
                    continue;
                }
                if let Ok(id) = v.parse::<u64>() {
                    out.push((id, *line));
                } else {
                    let key = v.to_ascii_uppercase();
                    let found = self.spelling.get(&key).and_then(|name| sets.get(name));
                    match found {
                        Some(members) => out.extend(members.iter().map(|&(id, _)| (id, *line))),
                        None => {
                            return Err(self.syntax(
                                *line,
                                format!(
                                    "{what}: '{}' is neither an id nor a {what} defined before",
                                    clip(v)
                                ),
                            ))
                        }
                    }
                }
            }
        }
        Ok(out)
    }

    fn nset(&mut self, p: &[(String, String)], data: &[(String, usize)], at: usize) -> R<()> {
        let Some(name) = self.set_param(p, "NSET", at)? else {
            return Err(self.syntax(at, "*NSET without NSET="));
        };
        let generate = p.iter().any(|(k, _)| k == "GENERATE");
        let mut members = self.members(
            generate,
            data,
            &self.nsets,
            "node set",
            self.file.nodes.len(),
        )?;
        if let Some(elset) = self.set_param(p, "ELSET", at)? {
            let Some(elements) = self.elsets.get(&elset) else {
                return Err(self.syntax(
                    at,
                    format!("*NSET, ELSET={elset}: no such element set defined before"),
                ));
            };
            for &(id, _) in elements {
                if let Some(&(k, solid)) = self.element_nodes.get(&id) {
                    let nodes = if solid {
                        &self.file.elements[k].nodes
                    } else {
                        &self.file.other_elements[k].nodes
                    };
                    members.extend(nodes.iter().map(|&n| (n, at)));
                }
            }
        }
        add_members(self.nsets.entry(name).or_default(), members);
        Ok(())
    }

    fn elset(&mut self, p: &[(String, String)], data: &[(String, usize)], at: usize) -> R<()> {
        let Some(name) = self.set_param(p, "ELSET", at)? else {
            return Err(self.syntax(at, "*ELSET without ELSET="));
        };
        let generate = p.iter().any(|(k, _)| k == "GENERATE");
        let members = self.members(
            generate,
            data,
            &self.elsets,
            "element set",
            self.element_nodes.len(),
        )?;
        add_members(self.elsets.entry(name).or_default(), members);
        Ok(())
    }

    fn surface(&mut self, p: &[(String, String)], data: &[(String, usize)], at: usize) -> R<()> {
        let Some(name) = self.set_param(p, "NAME", at)? else {
            return Err(self.syntax(at, "*SURFACE without NAME="));
        };
        let stype = p
            .iter()
            .find(|(k, _)| k == "TYPE")
            .map_or("ELEMENT".to_string(), |(_, v)| v.to_ascii_uppercase());
        match stype.as_str() {
            "NODE" => {
                let mut members = Vec::new();
                for (text, line) in data {
                    let t = Self::tokens(text);
                    let first = t.first().copied().unwrap_or("");
                    let one = vec![(first.to_string(), *line)];
                    members.extend(self.members(false, &one, &self.nsets, "node set", 0)?);
                }
                add_members(self.nsets.entry(name).or_default(), members);
            }
            "ELEMENT" => {
                let mut faces = Vec::new();
                for (text, line) in data {
                    let t = Self::tokens(text);
                    if t.len() != 2 {
                        return Err(self.syntax(
                            *line,
                            "*SURFACE, TYPE=ELEMENT: expected 'element or element set, Sn'",
                        ));
                    }
                    let side = t[1].to_ascii_uppercase();
                    let side = side
                        .strip_prefix('S')
                        .and_then(|s| s.parse::<usize>().ok())
                        .filter(|s| (1..=6).contains(s))
                        .ok_or_else(|| {
                            self.syntax(
                                *line,
                                format!("*SURFACE: side '{}' is not S1..S6", clip(t[1])),
                            )
                        })?;
                    let one = vec![(t[0].to_string(), *line)];
                    for (element, _) in self.members(false, &one, &self.elsets, "element set", 0)? {
                        faces.push(FileFace::Side {
                            element,
                            side,
                            line: *line,
                        });
                    }
                }
                self.file.face_sets.entry(name).or_default().extend(faces);
            }
            _ => {
                return Err(ImportError::Unsupported {
                    at: self.at(at),
                    what: format!(
                        "*SURFACE, TYPE={}: only TYPE=ELEMENT and TYPE=NODE are read",
                        clip(&stype)
                    ),
                })
            }
        }
        Ok(())
    }

    /// Sets by file ids into the file's sets.
    fn finish(self) -> R<()> {
        let file = self.file;
        let nodes: HashMap<u64, ()> = file.nodes.iter().map(|n| (n.id, ())).collect();
        for (name, members) in &self.nsets {
            let mut ids = Vec::with_capacity(members.len());
            for &(id, line) in members {
                if !nodes.contains_key(&id) {
                    return Err(ImportError::MissingMember {
                        at: file.place(line),
                        set: name.clone(),
                        what: "node",
                        id,
                    });
                }
                ids.push(id);
            }
            ids.sort_unstable();
            ids.dedup();
            file.node_sets.insert(name.clone(), ids);
        }
        for (name, members) in &self.elsets {
            let mut solids = Vec::new();
            let mut faces = Vec::new();
            let mut line_nodes = Vec::new();
            for &(id, line) in members {
                match self.element_nodes.get(&id) {
                    None => {
                        return Err(ImportError::MissingMember {
                            at: file.place(line),
                            set: name.clone(),
                            what: "element",
                            id,
                        })
                    }
                    Some(&(k, true)) => solids.push(k),
                    Some(&(k, false)) => {
                        let e = &file.other_elements[k];
                        if matches!(kind(&e.kind), Some(Kind::Surface(_))) {
                            faces.push(FileFace::Nodes {
                                nodes: e.nodes.clone(),
                                line: e.line,
                            });
                        } else {
                            line_nodes.extend(e.nodes.iter().copied());
                        }
                    }
                }
            }
            solids.sort_unstable();
            solids.dedup();
            if !solids.is_empty() {
                file.element_sets.insert(name.clone(), solids);
            }
            if !faces.is_empty() {
                file.face_sets
                    .entry(name.clone())
                    .or_default()
                    .extend(faces);
            }
            if !line_nodes.is_empty() && !self.nsets.contains_key(name) {
                line_nodes.sort_unstable();
                line_nodes.dedup();
                file.node_sets.insert(name.clone(), line_nodes);
            }
        }
        Ok(())
    }
}

/// Add `members` to a set, each id once (its first line kept): a set naming itself over and
/// over cannot grow beyond the ids the file defines.
fn add_members(set: &mut Vec<(u64, usize)>, members: Vec<(u64, usize)>) {
    set.extend(members);
    set.sort_by_key(|&(id, line)| (id, line));
    set.dedup_by_key(|m| m.0);
}

fn clip(t: &str) -> String {
    t.chars().take(40).collect()
}

/// An element's data line: its id and node numbers separated by `sep`, at most 16 entries a
/// line (Abaqus' and CalculiX's limit): the id and 15 nodes, then 16 nodes a line.
pub(crate) fn element_line(id: usize, nodes: impl Iterator<Item = usize>, sep: &str) -> String {
    let ids: Vec<String> = std::iter::once(id)
        .chain(nodes)
        .map(|v| v.to_string())
        .collect();
    let lines: Vec<String> = ids.chunks(16).map(|c| c.join(sep)).collect();
    lines.join(",\n")
}

/// Write `bodies` (name, solid group) of `mesh` at coordinates `x` as an Abaqus input file:
/// `*NODE`, `*ELEMENT, TYPE=C3D.., ELSET=BODY`, `*NSET` and `*SURFACE, TYPE=ELEMENT` for each
/// body's node and face sets, without the `BODY.` prefix (see the module documentation).
pub fn write(
    mesh: &Mesh,
    x: &[Vector3<f64>],
    bodies: &[(String, usize)],
    path: &Path,
) -> Result<(), ImportError> {
    let plan = super::gmsh::plan(mesh, x, bodies, path)?;
    let mut s = String::from("** Written by fricsens\n*NODE\n");
    for &n in &plan.nodes {
        s.push_str(&format!(
            "{}, {:?}, {:?}, {:?}\n",
            n + 1,
            x[n][0],
            x[n][1],
            x[n][2]
        ));
    }
    // elements, and the faces of each body's elements by sorted nodes
    let mut id = 0usize;
    let mut faces: HashMap<Vec<usize>, (usize, Shape, usize)> = HashMap::new();
    for (name, g, ..) in &plan.bodies {
        let group = &mesh.groups[*g];
        let Some(ty) = abaqus_type(group.shape) else {
            return Err(ImportError::Write {
                file: path.to_path_buf(),
                message: format!("body '{name}': {} has no Abaqus type", group.shape.name()),
            });
        };
        s.push_str(&format!("*ELEMENT, TYPE={ty}, ELSET={name}\n"));
        for k in 0..group.len() {
            id += 1;
            let e = group.element(k);
            s.push_str(&element_line(id, e.iter().map(|n| n + 1), ", "));
            s.push('\n');
            for (f, face) in group.shape.faces().iter().enumerate() {
                let mut key: Vec<usize> = face.nodes.iter().map(|&l| e[l]).collect();
                key.sort_unstable();
                faces.entry(key).or_insert((id, group.shape, f));
            }
        }
    }
    let mut nsets: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    let mut surfaces: BTreeMap<&str, Vec<(usize, usize)>> = BTreeMap::new();
    for (name, _, ns, fs) in &plan.bodies {
        for (set, v) in ns {
            nsets.entry(set).or_default().extend(v.iter().copied());
        }
        for (set, f) in fs {
            let list = surfaces.entry(set).or_default();
            for k in 0..f.len() {
                let mut key = f.nodes(k).to_vec();
                key.sort_unstable();
                let Some(&(e, shape, face)) = faces.get(&key) else {
                    return Err(ImportError::Write {
                        file: path.to_path_buf(),
                        message: format!(
                            "face set '{name}.{set}': face {:?} is a face of no element written",
                            f.nodes(k)
                        ),
                    });
                };
                // every face of a solid shape is an Abaqus side
                let side = side_of_face(shape, face).unwrap_or(0);
                list.push((e, side));
            }
        }
    }
    for (set, mut v) in nsets {
        v.sort_unstable();
        v.dedup();
        s.push_str(&format!("*NSET, NSET={set}\n"));
        for chunk in v.chunks(16) {
            let line: Vec<String> = chunk.iter().map(|n| (n + 1).to_string()).collect();
            s.push_str(&line.join(", "));
            s.push('\n');
        }
    }
    for (set, v) in surfaces {
        s.push_str(&format!("*SURFACE, TYPE=ELEMENT, NAME={set}\n"));
        for (e, side) in v {
            s.push_str(&format!("{e}, S{side}\n"));
        }
    }
    std::fs::write(path, s).map_err(|e| ImportError::Write {
        file: path.to_path_buf(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solid_types_and_their_variants_name_their_shapes() {
        for (t, shape) in [
            ("C3D8", Shape::Hex8),
            ("c3d8r", Shape::Hex8),
            ("C3D8I", Shape::Hex8),
            ("C3D20", Shape::Hex20),
            ("C3D20R", Shape::Hex20),
            ("C3D20RH", Shape::Hex20),
            ("C3D4", Shape::Tet4),
            ("C3D4H", Shape::Tet4),
            ("C3D10", Shape::Tet10),
            ("C3D10M", Shape::Tet10),
            ("C3D10H", Shape::Tet10),
            ("C3D6", Shape::Wedge6),
            ("C3D15", Shape::Wedge15),
            ("C3D15H", Shape::Wedge15),
        ] {
            assert!(matches!(kind(t), Some(Kind::Solid(s)) if s == shape), "{t}");
        }
        for t in ["C3D27", "C3D15V", "C3D5", "C3D8X2", "C3D"] {
            assert!(kind(t).is_none(), "{t}");
        }
        for shape in Shape::SOLIDS {
            let t = abaqus_type(shape).unwrap();
            assert!(matches!(kind(t), Some(Kind::Solid(s)) if s == shape), "{t}");
        }
        assert_eq!(abaqus_type(Shape::Line2), None);
    }
}
