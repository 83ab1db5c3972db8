//! Output: per-increment CSV of the responses and Newton records, and VTK XML unstructured
//! grids (`.vtu`, written with `vtkio`) of displacement and stress, with a `.pvd` collection so
//! ParaView plays the load history.

use crate::model::Model;
use crate::solver::Results;
use nalgebra::Vector3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vtkio::model::{
    Attribute, Attributes, ByteOrder, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// Output failures, naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// Creating or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// vtkio could not write a VTK file.
    #[error("{path}: VTK: {message}")]
    Vtk {
        /// The file.
        path: PathBuf,
        /// vtkio's message.
        message: String,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Write `history.csv`: one row per converged increment with time, Newton iterations,
/// cutbacks, final residual, and every response of the model.
pub fn write_history_csv(path: &Path, model: &Model, res: &Results) -> Result<(), OutputError> {
    let mut s = String::from("increment,time,iterations,cutbacks,residual");
    for r in &model.responses {
        let _ = write!(s, ",{}", r.name);
    }
    s.push('\n');
    for (k, t) in res.times.iter().enumerate() {
        let (it, cb, rn) = if k == 0 {
            (0, 0, 0.0)
        } else {
            let r = &res.records[k - 1];
            (
                r.iterations,
                r.cutbacks,
                r.residuals.last().copied().unwrap_or(0.0),
            )
        };
        let _ = write!(s, "{k},{t:.10e},{it},{cb},{rn:.6e}");
        for r in 0..model.responses.len() {
            let v = if k < res.states.len() {
                res.response_value(model, r, k)
            } else {
                f64::NAN
            };
            let _ = write!(s, ",{v:.12e}");
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(io(path))
}

/// Write `contact.csv`, long format: one row per hitting node of every pair at every stored
/// increment, with the node's number, its reference (`X`, `Y`, `Z`) and current (`x`, `y`,
/// `z`) coordinates, its state (0 open, 1 closed frictionless, 2 stick, 3 slip), normal force,
/// both contact pressures (`p_nominal` over the reference pressure area, `p_current` over the
/// deformed one: the Cauchy pressure CalculiX and Abaqus report) and friction force. The
/// numbers and coordinates are those of the VTK files.
pub fn write_contact_csv(path: &Path, model: &Model, res: &Results) -> Result<(), OutputError> {
    let mut s = String::from(
        "increment,time,pair,node,X,Y,Z,x,y,z,state,normal_force,p_nominal,p_current,friction_x,friction_y,friction_z\n",
    );
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    for (k, t) in res.times.iter().enumerate() {
        let (Some(c), Some(z)) = (res.contact.get(k), res.states.get(k)) else {
            continue;
        };
        for (p, pair) in model.contacts.iter().enumerate() {
            let first = res.contact_flat.get(p).copied().unwrap_or(0);
            let Some((nominal, current)) = c.pressures(pair, first) else {
                continue;
            };
            for (i, &n) in pair.hitting.iter().enumerate() {
                let f = first + i;
                if f >= c.choice.len() {
                    continue;
                }
                let u = &z[crate::model::node_dofs(n)];
                let (r, fr) = (x[n], c.traction[f]);
                let _ = writeln!(
                    s,
                    "{k},{t:.10e},{},{n},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e}",
                    pair.name,
                    r[0],
                    r[1],
                    r[2],
                    r[0] + u[0],
                    r[1] + u[1],
                    r[2] + u[2],
                    c.choice[f].state.code(),
                    c.normal_force[f],
                    nominal[i],
                    current[i],
                    fr[0],
                    fr[1],
                    fr[2]
                );
            }
        }
    }
    std::fs::write(path, s).map_err(io(path))
}

/// Write `profile.csv`, long format: one row per contact-pressure response (a station of a
/// pressure profile, or a node) at every stored increment, with the response's name, its pair,
/// its measure (`nominal` or `current`), how many hitting nodes it spans, the mean reference
/// (`X`, `Y`, `Z`) and current (`x`, `y`, `z`) coordinates of those nodes, and the pressure.
/// A plotting script reads a profile from it directly, by coordinate.
pub fn write_profile_csv(path: &Path, model: &Model, res: &Results) -> Result<(), OutputError> {
    let mut s = String::from("increment,time,response,pair,measure,nodes,X,Y,Z,x,y,z,pressure\n");
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    for (k, t) in res.times.iter().enumerate() {
        let Some(z) = res.states.get(k) else { continue };
        for (r, resp) in model.responses.iter().enumerate() {
            let crate::response::ResponseKind::ContactPressure {
                pair,
                nodes,
                measure,
            } = &resp.kind
            else {
                continue;
            };
            let hitting = &model.contacts[*pair].hitting;
            let n = nodes.len().max(1) as f64;
            let (mut reference, mut current) = (Vector3::zeros(), Vector3::zeros());
            for i in nodes {
                let node = hitting[*i];
                let u = &z[crate::model::node_dofs(node)];
                reference += x[node];
                current += x[node] + Vector3::new(u[0], u[1], u[2]);
            }
            let (a, b) = (reference / n, current / n);
            let _ = writeln!(
                s,
                "{k},{t:.10e},{},{},{},{},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e},{:.12e}",
                resp.name,
                model.contacts[*pair].name,
                measure.name(),
                nodes.len(),
                a[0],
                a[1],
                a[2],
                b[0],
                b[1],
                b[2],
                res.response_value(model, r, k)
            );
        }
    }
    std::fs::write(path, s).map_err(io(path))
}

/// Point and cell fields of one increment beyond displacement and stress.
#[derive(Default)]
pub struct ExtraFields {
    /// `(name, components, values)` per point.
    pub point: Vec<(String, u32, Vec<f64>)>,
    /// `(name, components, values)` per cell.
    pub cell: Vec<(String, u32, Vec<f64>)>,
}

/// Write one `.vtu` file: reference coordinates, displacement, Cauchy stress and von Mises
/// stress per element, and any extra fields.
pub fn write_vtu(
    path: &Path,
    model: &Model,
    z: &[f64],
    stress: &[nalgebra::Matrix3<f64>],
    extra: &ExtraFields,
) -> Result<(), OutputError> {
    let x = model.mesh.coordinates::<f64>(&model.mesh.block_geometry());
    let n = x.len();
    let mut points = Vec::with_capacity(3 * n);
    let mut disp = Vec::with_capacity(3 * n);
    for (i, p) in x.iter().enumerate() {
        points.extend_from_slice(&[p[0], p[1], p[2]]);
        disp.extend_from_slice(&z[crate::model::node_dofs(i)]);
    }
    let ne = model.mesh.n_elements();
    let mut connectivity = Vec::new();
    let mut offsets = Vec::with_capacity(ne);
    let mut types = Vec::with_capacity(ne);
    for (shape, c) in model.mesh.elements() {
        connectivity.extend(shape.vtk_order().iter().map(|&k| c[k] as u64));
        offsets.push(connectivity.len() as u64);
        types.push(shape.vtk_cell());
    }
    let mut sig = Vec::with_capacity(6 * ne);
    let mut mises = Vec::with_capacity(ne);
    for s in stress {
        sig.extend_from_slice(&crate::fields::stress_components(s));
        mises.push(crate::fields::von_mises(s));
    }
    let arr = |name: &str, comps: u32, data: Vec<f64>| {
        Attribute::DataArray(DataArray {
            name: name.to_string(),
            elem: if comps == 1 {
                ElementType::Scalars {
                    num_comp: 1,
                    lookup_table: None,
                }
            } else {
                ElementType::Generic(comps)
            },
            data: IOBuffer::new(data),
        })
    };
    let mut point = vec![arr("displacement", 3, disp)];
    for (name, c, v) in &extra.point {
        point.push(arr(name, *c, v.clone()));
    }
    let mut cell = vec![arr("cauchy_stress", 6, sig), arr("von_mises", 1, mises)];
    for (name, c, v) in &extra.cell {
        cell.push(arr(name, *c, v.clone()));
    }
    let vtk = Vtk {
        version: Version::new(),
        title: model
            .bodies
            .first()
            .map(|b| b.name.clone())
            .unwrap_or_default(),
        byte_order: ByteOrder::native(),
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: IOBuffer::new(points),
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity,
                    offsets,
                },
                types,
            },
            data: Attributes { point, cell },
        }),
    };
    vtk.export(path).map_err(|e| OutputError::Vtk {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Write a ParaView collection (`.pvd`) listing `(time, file)` pairs.
pub fn write_pvd(path: &Path, files: &[(f64, String)]) -> Result<(), OutputError> {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n",
    );
    for (t, f) in files {
        let _ = writeln!(
            s,
            "    <DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{f}\"/>"
        );
    }
    s.push_str("  </Collection>\n</VTKFile>\n");
    std::fs::write(path, s).map_err(io(path))
}

/// Contact state map of increment `k` as point fields: `contact_state` (-1 not a hitting node,
/// 0 open, 1 closed frictionless, 2 stick, 3 slip), `normal_force`, the contact pressure over
/// the node's reference pressure area (`contact_pressure_nominal`) and over its current one
/// (`contact_pressure_current`, the Cauchy pressure CalculiX and Abaqus report),
/// `friction_force` (its direction is the slip direction) and `contact_force`.
pub fn contact_fields(model: &Model, res: &Results, k: usize) -> ExtraFields {
    let mut extra = ExtraFields::default();
    let Some(c) = res.contact.get(k) else {
        return extra;
    };
    if model.contacts.is_empty() {
        return extra;
    }
    let n = model.mesh.n_nodes();
    let mut state = vec![-1.0; n];
    let mut normal = vec![0.0; n];
    let mut nominal = vec![0.0; n];
    let mut current = vec![0.0; n];
    let mut friction = vec![0.0; 3 * n];
    let mut force = vec![0.0; 3 * n];
    for (p, pair) in model.contacts.iter().enumerate() {
        let first = res.contact_flat.get(p).copied().unwrap_or(0);
        let Some((p_nominal, p_current)) = c.pressures(pair, first) else {
            continue;
        };
        for (i, &node) in pair.hitting.iter().enumerate() {
            let f = first + i;
            if f >= c.choice.len() {
                continue;
            }
            state[node] = c.choice[f].state.code();
            normal[node] += c.normal_force[f];
            nominal[node] += p_nominal[i];
            current[node] += p_current[i];
            for j in 0..3 {
                // three components per node, as the nodal unknowns
                friction[crate::model::node_dof(node, j)] += c.traction[f][j];
                force[crate::model::node_dof(node, j)] += c.force[f][j];
            }
        }
    }
    extra.point.push(("contact_state".into(), 1, state));
    extra.point.push(("normal_force".into(), 1, normal));
    extra
        .point
        .push(("contact_pressure_nominal".into(), 1, nominal));
    extra
        .point
        .push(("contact_pressure_current".into(), 1, current));
    extra.point.push(("friction_force".into(), 3, friction));
    extra.point.push(("contact_force".into(), 3, force));
    extra
}

/// The point and cell fields of stored increment `k` beyond displacement and stress: the
/// contact fields ([`contact_fields`]), `stick_slip` (per node: 0 not in frictional contact,
/// 1 stick, 2 slip) and the `equivalent_plastic_strain` per element (its Gauss-point average,
/// [`crate::fields::equivalent_plastic_strain`]).
pub fn primal_fields(model: &Model, res: &Results, k: usize) -> ExtraFields {
    let mut extra = contact_fields(model, res, k);
    if let Some((_, _, state)) = extra.point.iter().find(|f| f.0 == "contact_state") {
        let map = state
            .iter()
            .map(|s| match *s as i32 {
                2 => 1.0,
                3 => 2.0,
                _ => 0.0,
            })
            .collect();
        extra.point.push(("stick_slip".into(), 1, map));
    }
    let dofs = model.dof_map();
    let eqps = match res.histories.get(k) {
        Some(h) => (0..model.mesh.n_elements())
            .map(|e| crate::fields::equivalent_plastic_strain(model, &dofs, h, e))
            .collect(),
        None => vec![0.0; model.mesh.n_elements()],
    };
    extra
        .cell
        .push(("equivalent_plastic_strain".into(), 1, eqps));
    extra
}

/// Write `vtk/` of a sensitivity run with fields (`Settings::fields`): one `.vtu` per
/// increment with the primal fields ([`write_vtu`], [`primal_fields`]) and, for every
/// parameter `P` and field `F` of [`crate::fields::state_fields`], its derivative `d(F)/d(P)`;
/// and `vtk/sensitivity.pvd`, the collection of them.
pub fn write_sensitivity_vtk(
    dir: &Path,
    model: &Model,
    res: &Results,
    sens: &crate::sensitivity::SensitivityResults,
) -> Result<(), OutputError> {
    let vtk = dir.join("vtk");
    std::fs::create_dir_all(&vtk).map_err(io(&vtk))?;
    let mut files = Vec::new();
    for inc in &sens.fields {
        let k = inc.increment;
        let Some(z) = res.states.get(k) else { break };
        let mut extra = primal_fields(model, res, k);
        for (p, fields) in sens.parameters.iter().zip(&inc.derivatives) {
            for f in fields {
                let entry = (
                    format!("d({})/d({p})", f.name),
                    f.components,
                    f.values.clone(),
                );
                match f.location {
                    crate::fields::Location::Point => extra.point.push(entry),
                    crate::fields::Location::Cell => extra.cell.push(entry),
                }
            }
        }
        let name = format!("step_{k:04}.vtu");
        write_vtu(&vtk.join(&name), model, z, &res.stresses[k], &extra)?;
        files.push((inc.time, name));
    }
    write_pvd(&vtk.join("sensitivity.pvd"), &files)
}

/// The field a field parameter belongs to, and where it sits on the mesh: its name without
/// the bracketed index (`upper.sigma_y[12]` belongs to `upper.sigma_y`), and the cell or
/// point it is of. `None` for a parameter of the whole model.
fn field_member(model: &Model, p: &crate::design::Parameter) -> Option<(String, Location)> {
    use crate::model::DesignParam;
    let group = p.name.split('[').next().unwrap_or(&p.name).to_string();
    match p.targets[..] {
        [DesignParam::ElementMaterial { element, .. }] => Some((group, Location::Cell(element))),
        [DesignParam::NodeFriction { pair, node, .. }] => {
            let hitting = *model.contacts.get(pair)?.hitting.get(node)?;
            Some((group, Location::Point(hitting)))
        }
        [DesignParam::NodeShape { node, .. }] => Some((group, Location::Point(node))),
        _ => None,
    }
}

/// A field parameter's cell (element) or point (node).
#[derive(Clone, Copy, PartialEq)]
enum Location {
    Cell(usize),
    Point(usize),
}

/// Write `vtk/parameters_NNNN.vtu` for every increment of `sens` and their collection
/// `vtk/parameters.pvd`, when `params` holds field parameters (`BODY.PARAM[E]`,
/// `PAIR.PARAM[N]`, `SET.x[N]`): each response's derivative in every member of each field
/// drawn on the mesh, `d(RESPONSE)/d(FIELD)`, as cell data for a material field (per element)
/// and as point data for a friction field (at each hitting node) or a nodal shape field (per
/// node and axis); cells and points outside the field hold 0. The state drawn beside them is
/// the increment's where `res` kept it, else the reference configuration. Returns the files
/// written (none without field parameters).
pub fn write_parameter_fields_vtk(
    dir: &Path,
    model: &Model,
    res: &Results,
    sens: &crate::sensitivity::SensitivityResults,
    params: &[crate::design::Parameter],
) -> Result<Vec<PathBuf>, OutputError> {
    let members: Vec<Option<(String, Location)>> =
        params.iter().map(|p| field_member(model, p)).collect();
    let mut groups: Vec<(String, bool)> = Vec::new();
    for (g, loc) in members.iter().flatten() {
        let cell = matches!(loc, Location::Cell(_));
        if !groups.iter().any(|(n, _)| n == g) {
            groups.push((g.clone(), cell));
        }
    }
    if groups.is_empty() {
        return Ok(Vec::new());
    }
    let vtk = dir.join("vtk");
    std::fs::create_dir_all(&vtk).map_err(io(&vtk))?;
    let (ne, nn) = (model.mesh.n_elements(), model.mesh.n_nodes());
    let mut files = Vec::new();
    let mut written = Vec::new();
    for inc in &sens.increments {
        let mut extra = ExtraFields::default();
        for (r, name) in sens.responses.iter().enumerate() {
            for (g, cell) in &groups {
                let mut v = vec![0.0; if *cell { ne } else { nn }];
                for (k, m) in members.iter().enumerate() {
                    match m {
                        Some((mg, Location::Cell(i) | Location::Point(i))) if mg == g => {
                            v[*i] = inc.derivatives[r][k];
                        }
                        _ => {}
                    }
                }
                let entry = (format!("d({name})/d({g})"), 1, v);
                if *cell {
                    extra.cell.push(entry);
                } else {
                    extra.point.push(entry);
                }
            }
        }
        let k = res.times.iter().position(|t| (t - inc.time).abs() < 1e-12);
        let kept = k.filter(|k| res.states.len() == res.times.len() && *k < res.stresses.len());
        let zero_z = vec![0.0; res.states.last().map_or(3 * nn, Vec::len)];
        let zero_s = vec![nalgebra::Matrix3::zeros(); ne];
        let (z, stress) = match kept {
            Some(k) => (&res.states[k], &res.stresses[k]),
            None if Some(inc.time) == res.times.last().copied() && !res.states.is_empty() => (
                res.states.last().expect("not empty"),
                res.stresses.last().unwrap_or(&zero_s),
            ),
            None => (&zero_z, &zero_s),
        };
        let name = format!("parameters_{:04}.vtu", inc.increment);
        let path = vtk.join(&name);
        write_vtu(&path, model, z, stress, &extra)?;
        files.push((inc.time, name));
        written.push(path);
    }
    write_pvd(&vtk.join("parameters.pvd"), &files)?;
    Ok(written)
}

/// Which increments [`write_run`] writes as VTK files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VtkOutput {
    /// None (`fricsens run --no-vtk`).
    None,
    /// Every `N`-th stored increment (the initial state is the 0th) and the last one.
    Every(usize),
}

impl VtkOutput {
    /// Whether stored increment `k` of `n` is written.
    fn writes(self, k: usize, n: usize) -> bool {
        match self {
            VtkOutput::None => false,
            VtkOutput::Every(every) => k % every.max(1) == 0 || k + 1 == n,
        }
    }
}

/// Write the whole run: `history.csv`, `contact.csv` (with contact pairs), `profile.csv` (with
/// contact-pressure responses), `newton.json`, and,
/// as `vtk` says, `vtk/` with one
/// `.vtu` per written increment and the `.pvd` collection of them.
pub fn write_run(
    dir: &Path,
    model: &Model,
    res: &Results,
    vtk: VtkOutput,
) -> Result<(), OutputError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    write_history_csv(&dir.join("history.csv"), model, res)?;
    if !model.contacts.is_empty() {
        write_contact_csv(&dir.join("contact.csv"), model, res)?;
    }
    let profiles = (model.responses.iter()).any(|r| {
        matches!(
            r.kind,
            crate::response::ResponseKind::ContactPressure { .. }
        )
    });
    if profiles {
        write_profile_csv(&dir.join("profile.csv"), model, res)?;
    }
    let p = dir.join("newton.json");
    let json = serde_json::to_string_pretty(&res.records).expect("records serialise");
    std::fs::write(&p, json).map_err(io(&p))?;
    if vtk == VtkOutput::None {
        return Ok(());
    }
    std::fs::create_dir_all(dir.join("vtk")).map_err(io(dir))?;
    let mut files = Vec::new();
    let stored = res.states.len().min(res.times.len());
    for (k, t) in res.times.iter().enumerate() {
        let Some(z) = res.states.get(k) else { break };
        if !vtk.writes(k, stored) {
            continue;
        }
        let name = format!("step_{k:04}.vtu");
        write_vtu(
            &dir.join("vtk").join(&name),
            model,
            z,
            &res.stresses[k],
            &primal_fields(model, res, k),
        )?;
        files.push((*t, name));
    }
    write_pvd(&dir.join("vtk").join("history.pvd"), &files)
}
