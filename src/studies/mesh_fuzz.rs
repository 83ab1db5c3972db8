//! The mesh readers' fuzzer: mutated Gmsh and Abaqus files, none of which may panic.
//!
//! Seeds are real files: a graded 2 x 2 x 2 block written by fricsens' own writers (MSH 4.1
//! ASCII and binary, `.inp`), and any files the user adds (their mesher's output, the
//! repository's fixtures). Each mutant applies one to three edits to a seed — truncation at a
//! random byte, a line deleted, duplicated or swapped with another, a number replaced by an
//! extreme or malformed one (`1e308`, `NaN`, `-1`, a 20-digit integer, an empty token, ...), or
//! random bit flips — and is read by [`crate::mesh::read`] and imported whole and set by set.
//! A mutant must read to a mesh or to a typed [`ImportError`] that names the file; a panic is a
//! bug, and the mutant is kept in the corpus directory (`tests/corpus/meshes/` in the
//! repository, which the test suite replays).
//!
//! `fricsens fuzz-meshes` runs it from the command line; the test suite runs 2,000 mutants.

use crate::element::Shape;
use crate::mesh::import::ImportError;
use crate::mesh::{abaqus, gmsh, Axis, BlockSpec, Mesh, Zone};
use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// xorshift64*: a small deterministic generator (a campaign is reproduced from its seed).
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        // xorshift has the fixed point 0
        Rng(seed.max(1))
    }
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Spans of numeric-looking tokens.
fn numbers(b: &[u8]) -> Vec<(usize, usize)> {
    let num = |c: u8| c.is_ascii_digit() || matches!(c, b'.' | b'-' | b'+' | b'e' | b'E');
    let mut v = Vec::new();
    let mut k = 0;
    while k < b.len() {
        if num(b[k]) {
            let s = k;
            while k < b.len() && num(b[k]) {
                k += 1;
            }
            if b[s..k].iter().any(u8::is_ascii_digit) {
                v.push((s, k));
            }
        } else {
            k += 1;
        }
    }
    v
}

/// Numbers a mutant may put in place of one: extremes, signs, malformed tokens, and small
/// counts and versions that a header might hold.
const REPLACEMENTS: [&[u8]; 14] = [
    b"1e308",
    b"-1",
    b"NaN",
    b"inf",
    b"999999999999",
    b"18446744073709551616",
    b"0",
    b"-0",
    b"abc",
    b"",
    b"4.1",
    b"2",
    b"1e-300",
    b"3",
];

/// One to three random edits of `seed`.
fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(3) {
        let mut lines: Vec<Vec<u8>> = b.split(|&c| c == b'\n').map(<[u8]>::to_vec).collect();
        match rng.below(7) {
            0 => {
                let at = rng.below(b.len() + 1);
                b.truncate(at);
            }
            1 if lines.len() > 1 => {
                let k = rng.below(lines.len());
                lines.remove(k);
                b = lines.join(&b'\n');
            }
            2 => {
                let k = rng.below(lines.len());
                let l = lines[k].clone();
                lines.insert(k, l);
                b = lines.join(&b'\n');
            }
            3 => {
                let (i, j) = (rng.below(lines.len()), rng.below(lines.len()));
                lines.swap(i, j);
                b = lines.join(&b'\n');
            }
            4 | 5 => {
                let spans = numbers(&b);
                if !spans.is_empty() {
                    let (s, e) = spans[rng.below(spans.len())];
                    let with = REPLACEMENTS[rng.below(REPLACEMENTS.len())];
                    b.splice(s..e, with.iter().copied());
                }
            }
            _ => {
                if !b.is_empty() {
                    for _ in 0..1 + rng.below(4) {
                        let k = rng.below(b.len());
                        b[k] ^= 1 << rng.below(8);
                    }
                }
            }
        }
    }
    b
}

/// A seed file: its extension (which reader takes it) and its bytes.
#[derive(Clone, Debug)]
pub struct SeedFile {
    /// Where it came from (for the report).
    pub name: String,
    /// `msh` or `inp`.
    pub extension: String,
    /// Contents.
    pub bytes: Vec<u8>,
}

/// The built-in seeds: a graded 2 x 2 x 2 block at an odd origin (full mantissas), of hex8,
/// hex20 and tet10 elements (the quadratic ones' node orders and `.inp` continuation lines),
/// each written as MSH 4.1 ASCII, MSH 4.1 binary and `.inp`, with its six sides as sets.
pub fn builtin_seeds() -> Result<Vec<SeedFile>, ImportError> {
    // one folder per call, so that concurrent callers do not share files
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir =
        std::env::temp_dir().join(format!("fricsens-mesh-seeds-{}-{call}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| ImportError::Io {
        file: dir.clone(),
        message: e.to_string(),
    })?;
    let mut out = Vec::new();
    for shape in [Shape::Hex8, Shape::Hex20, Shape::Tet10] {
        let mut m = Mesh::default();
        m.add_block(BlockSpec {
            element: shape,
            name: "b".into(),
            origin: [0.3, -1.7, 2.1],
            x: Axis {
                length: 1.1,
                zones: vec![Zone {
                    fraction: 1.0,
                    elements: 2,
                    ratio: 3.0,
                }],
            },
            y: Axis::uniform(0.7, 2),
            z: Axis::uniform(0.9 / 7.0, 2),
        })
        .expect("a valid block");
        let x = m.coordinates::<f64>(&m.block_geometry());
        let bodies = vec![("b".to_string(), 0)];
        for (name, ext, k) in [
            ("block.msh (ASCII)", "msh", 0),
            ("block.msh (binary)", "msh", 1),
            ("block.inp", "inp", 2),
        ] {
            let path = dir.join(format!("seed-{}-{k}.{ext}", shape.name()));
            match k {
                0 => gmsh::write(&m, &x, &bodies, &path, false)?,
                1 => gmsh::write(&m, &x, &bodies, &path, true)?,
                _ => abaqus::write(&m, &x, &bodies, &path)?,
            }
            let bytes = std::fs::read(&path).map_err(|e| ImportError::Io {
                file: path.clone(),
                message: e.to_string(),
            })?;
            out.push(SeedFile {
                name: format!("{} {name}", shape.name()),
                extension: ext.into(),
                bytes,
            });
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out)
}

/// A seed from a file of the user's (`.msh` or `.inp`).
pub fn seed_from(path: &Path) -> Result<SeedFile, ImportError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .filter(|e| e == "msh" || e == "inp")
        .ok_or_else(|| ImportError::UnknownFormat {
            file: path.to_path_buf(),
        })?;
    let bytes = std::fs::read(path).map_err(|e| ImportError::Io {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(SeedFile {
        name: path.display().to_string(),
        extension,
        bytes,
    })
}

/// What to fuzz.
#[derive(Clone, Debug)]
pub struct MeshFuzzOptions {
    /// Number of mutants.
    pub mutants: usize,
    /// The generator's seed.
    pub seed: u64,
    /// The seed files, taken in turn.
    pub seeds: Vec<SeedFile>,
    /// Files an `*INCLUDE` of a seed names, copied beside each mutant.
    pub includes: Vec<PathBuf>,
    /// Where a panicking mutant is kept (`panic-SEED-K.EXT`).
    pub corpus: Option<PathBuf>,
}

/// What a campaign found.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MeshFuzzReport {
    /// Mutants read.
    pub mutants: usize,
    /// Read to a mesh.
    pub accepted: usize,
    /// Refused with a typed error, by error kind.
    pub refused: BTreeMap<String, usize>,
    /// Refusals whose message does not name the file: `(mutant, message)`.
    pub unnamed: Vec<(usize, String)>,
    /// Panics: `(mutant, message, kept as)`.
    pub panics: Vec<(usize, String, Option<PathBuf>)>,
    /// The slowest mutant and its time, seconds.
    pub slowest: (usize, f64),
    /// Wall time of the campaign, seconds.
    pub seconds: f64,
}

impl MeshFuzzReport {
    /// No panic and every refusal names its file.
    pub fn clean(&self) -> bool {
        self.panics.is_empty() && self.unnamed.is_empty()
    }

    /// Refusals in all.
    pub fn refused_total(&self) -> usize {
        self.refused.values().sum()
    }

    /// The report as Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# Mesh readers' fuzzer\n\n{} mutants in {:.1} s: {} read to a mesh, {} refused with a typed error, {} panics, {} refusals not naming the file; slowest mutant {} in {:.1} ms.\n\n| error | mutants |\n|---|---|\n",
            self.mutants,
            self.seconds,
            self.accepted,
            self.refused_total(),
            self.panics.len(),
            self.unnamed.len(),
            self.slowest.0,
            1e3 * self.slowest.1
        );
        for (kind, n) in &self.refused {
            s += &format!("| {kind} | {n} |\n");
        }
        for (k, msg, kept) in &self.panics {
            s += &format!(
                "\n- mutant {k} panicked: {msg} (kept as {})",
                kept.as_ref()
                    .map_or("nothing".into(), |p| p.display().to_string())
            );
        }
        for (k, msg) in &self.unnamed {
            s += &format!("\n- mutant {k}: the error does not name the file: {msg}");
        }
        s
    }
}

/// The error's kind: its variant's name.
fn kind(e: &ImportError) -> String {
    let debug = format!("{e:?}");
    debug
        .split(|c: char| !c.is_alphanumeric())
        .next()
        .unwrap_or("?")
        .to_string()
}

/// Read and import `path` whole and set by set, as a scene would: the refusals of single sets
/// (a node set is no body, say), or the refusal of the whole file.
pub fn read_and_import(path: &Path) -> Result<Vec<ImportError>, ImportError> {
    let f = crate::mesh::read(path)?;
    let mut m = Mesh::default();
    f.add_to(&mut m, "b", None)?;
    let mut refused = Vec::new();
    for name in f.set_names() {
        if let Err(e) = f.add_to(&mut m, &name, Some(&name)) {
            refused.push(e);
        }
    }
    Ok(refused)
}

/// Read `path` catching a panic: `Err(message)` if it panicked.
pub fn survives(path: &Path) -> Result<Result<Vec<ImportError>, ImportError>, String> {
    catch_unwind(AssertUnwindSafe(|| read_and_import(path))).map_err(|p| {
        p.downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "a panic".into())
    })
}

/// Run a campaign in `dir` (a scratch directory, made if needed). A panic's message also goes
/// through the panic hook (the command line silences it for the campaign).
pub fn run(opts: &MeshFuzzOptions, dir: &Path) -> Result<MeshFuzzReport, ImportError> {
    let io = |p: &Path| {
        let path = p.to_path_buf();
        move |e: std::io::Error| ImportError::Io {
            file: path,
            message: e.to_string(),
        }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    for inc in &opts.includes {
        if let Some(name) = inc.file_name() {
            std::fs::copy(inc, dir.join(name)).map_err(io(inc))?;
        }
    }
    let t0 = Instant::now();
    let mut rng = Rng::new(opts.seed);
    let mut report = MeshFuzzReport {
        mutants: opts.mutants,
        ..Default::default()
    };
    let mut slowest = (0, Duration::ZERO);
    if opts.seeds.is_empty() {
        return Ok(report);
    }
    for k in 0..opts.mutants {
        let seed = &opts.seeds[k % opts.seeds.len()];
        let bytes = mutate(&seed.bytes, &mut rng);
        let path = dir.join(format!("mutant.{}", seed.extension));
        std::fs::write(&path, &bytes).map_err(io(&path))?;
        let t = Instant::now();
        let outcome = survives(&path);
        if t.elapsed() > slowest.1 {
            slowest = (k, t.elapsed());
        }
        // an error names the mutant, or the included file it comes from
        let named = |msg: &str| {
            msg.contains("mutant.")
                || (opts.includes.iter())
                    .filter_map(|p| p.file_name()?.to_str())
                    .any(|n| msg.contains(n))
        };
        match outcome {
            Ok(Ok(sets)) => {
                report.accepted += 1;
                for e in sets {
                    let msg = e.to_string();
                    if !named(&msg) {
                        report.unnamed.push((k, msg));
                    }
                }
            }
            Ok(Err(e)) => {
                *report.refused.entry(kind(&e)).or_default() += 1;
                let msg = e.to_string();
                if !named(&msg) {
                    report.unnamed.push((k, msg));
                }
            }
            Err(msg) => {
                let kept = match &opts.corpus {
                    Some(c) => {
                        std::fs::create_dir_all(c).map_err(io(c))?;
                        let keep = c.join(format!("panic-{}-{k}.{}", opts.seed, seed.extension));
                        std::fs::write(&keep, &bytes).map_err(io(&keep))?;
                        Some(keep)
                    }
                    None => None,
                };
                report.panics.push((k, msg, kept));
            }
        }
    }
    report.slowest = (slowest.0, slowest.1.as_secs_f64());
    report.seconds = t0.elapsed().as_secs_f64();
    Ok(report)
}
