//! [`Scene::build`]: a scene validated and turned into a [`Model`] — the mesh from the blocks,
//! bodies, loads, contact pairs with their derived defaults (tributary areas, constraint scales,
//! search radius, tangential penalty), responses.

use super::*;
use crate::contact::geometry::RigidSurface;
use crate::contact::{setup, ContactPair, MotionControl, NormalLaw, RigidMotion, Target};
use crate::element::{Shape, SpringSet};
use crate::mesh::{Axis, Mesh};
use crate::model::{Amplitude, Body, Model, NodalLoad, Prescribed};
use crate::response::{Response, ResponseKind};

impl Scene {
    /// Node sets named `A & B` (e.g. `upper.xmax & upper.ymin`, an edge) are the intersection
    /// of the named node sets: add every one the scene refers to.
    fn add_intersections(&self, mesh: &mut Mesh) -> Result<(), SceneError> {
        let mut names: Vec<(String, String)> = Vec::new();
        for (i, p) in self.prescribed.iter().enumerate() {
            names.push((p.set.clone(), format!("prescribed[{i}].set")));
        }
        for (i, l) in self.loads.iter().enumerate() {
            names.push((l.set.clone(), format!("loads[{i}].set")));
        }
        for (i, c) in self.contacts.iter().enumerate() {
            names.push((c.hitting.clone(), format!("contacts[{i}].hitting")));
        }
        for (i, r) in self.responses.iter().enumerate() {
            if let ResponseSpec::Reaction { set, .. } | ResponseSpec::Displacement { set, .. } = r {
                names.push((set.clone(), format!("responses[{i}].set")));
            }
        }
        for (i, s) in self.springs.iter().enumerate() {
            names.push((s.a.clone(), format!("springs[{i}].a")));
            if let Some(b) = &s.b {
                names.push((b.clone(), format!("springs[{i}].b")));
            }
        }
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        for (name, field) in names {
            if mesh.node_sets.contains_key(&name) {
                continue;
            }
            let nodes =
                set_expression(&name, &mesh.node_sets, &x).map_err(|why| invalid(&field, why))?;
            if let Some(nodes) = nodes {
                mesh.node_sets.insert(name, nodes);
            }
        }
        Ok(())
    }

    /// Read a body's mesh file and add its elements (one group) and sets (`NAME.SET`) to
    /// `mesh`, coordinates times the source's scale; returns the group.
    fn add_mesh_body(
        &self,
        mesh: &mut Mesh,
        source: &MeshSource,
        at: &str,
    ) -> Result<usize, SceneError> {
        if !(source.scale.is_finite() && source.scale > 0.0) {
            return Err(invalid(
                &format!("{at}.scale"),
                format!("must be positive and finite, got {}", source.scale),
            ));
        }
        let path = resolve(source.folder.as_deref(), &source.file);
        let file =
            crate::mesh::read(&path).map_err(|e| invalid(&format!("{at}.mesh"), e.to_string()))?;
        let body = file
            .add_to(mesh, &source.name, source.set.as_deref())
            .map_err(|e| invalid(&format!("{at}.mesh"), e.to_string()))?;
        if source.scale != 1.0 {
            for &n in &body.nodes {
                if let crate::mesh::NodePlace::Free(x) = &mut mesh.places[n] {
                    for v in x.iter_mut() {
                        *v *= source.scale;
                    }
                }
            }
        }
        Ok(body.group)
    }

    /// A shape map of the scene on the mesh so far (module [`crate::mesh::shape_map`]).
    fn shape_map(
        &self,
        mesh: &Mesh,
        bodies: &[Body],
        sh: &ShapeSpec,
        at: &str,
    ) -> Result<crate::mesh::ShapeMap, SceneError> {
        use crate::mesh::{MapKind, ShapeMap};
        if self.shapes.iter().filter(|o| o.name == sh.name).count() > 1 {
            return Err(invalid(
                &format!("{at}.name"),
                format!("two shape maps are named '{}'", sh.name),
            ));
        }
        let node_set = |name: &str, field: &str| -> Result<Vec<usize>, SceneError> {
            match mesh.node_sets.get(name) {
                Some(v) if !v.is_empty() => Ok(v.clone()),
                _ => Err(invalid(field, format!("no node set named '{name}'"))),
            }
        };
        let body = || -> Result<&Body, SceneError> {
            bodies.iter().find(|b| b.name == sh.nodes).ok_or_else(|| {
                invalid(
                    &format!("{at}.nodes"),
                    format!(
                        "a morph or boundary map names a body; no body '{}'",
                        sh.nodes
                    ),
                )
            })
        };
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let bad = |e: crate::mesh::ShapeMapError| invalid(at, e.to_string());
        let affine = |kind: MapKind, reference: f64| {
            node_set(&sh.nodes, &format!("{at}.nodes")).map(|nodes| (nodes, kind, reference))
        };
        let (nodes, kind, reference) = match &sh.map {
            MapSpec::Translate { direction } => affine(
                MapKind::Translate {
                    direction: *direction,
                },
                0.0,
            )?,
            MapSpec::Rotate { centre, axis } => affine(
                MapKind::Rotate {
                    centre: *centre,
                    axis: *axis,
                },
                0.0,
            )?,
            MapSpec::Scale { centre, axis } => affine(
                MapKind::Scale {
                    centre: *centre,
                    axis: *axis,
                },
                1.0,
            )?,
            MapSpec::Morph { mesh: file, set } => {
                let b = body()?;
                let source = self.bodies.iter().find_map(|s| match &s.geometry {
                    BodyGeometry::Mesh(m) if m.name == b.name => Some(m),
                    _ => None,
                });
                let Some(source) = source else {
                    return Err(invalid(
                        &format!("{at}.nodes"),
                        format!(
                            "body '{}' is not read from a mesh file: a morph needs one",
                            b.name
                        ),
                    ));
                };
                let path = resolve(source.folder.as_deref(), file);
                let other = crate::mesh::read(&path)
                    .map_err(|e| invalid(&format!("{at}.map.mesh"), e.to_string()))?;
                let mut scratch = Mesh::default();
                let imported = other
                    .add_to(
                        &mut scratch,
                        &b.name,
                        set.as_deref().or(source.set.as_deref()),
                    )
                    .map_err(|e| invalid(&format!("{at}.map.mesh"), e.to_string()))?;
                let xb = scratch.coordinates::<f64>(&[]);
                let mine = &mesh.groups[b.group];
                let theirs = &scratch.groups[imported.group];
                let topology = |what: String| {
                    invalid(
                        &format!("{at}.map.mesh"),
                        format!(
                            "{}: {what}: a morph needs the same topology",
                            path.display()
                        ),
                    )
                };
                if mine.shape != theirs.shape || mine.nodes.len() != theirs.nodes.len() {
                    return Err(topology(format!(
                        "{} {} elements against the body's {} {}",
                        theirs.len(),
                        theirs.shape.name(),
                        mine.len(),
                        mine.shape.name()
                    )));
                }
                let mut partner: std::collections::BTreeMap<usize, usize> = Default::default();
                for (k, (&a, &bn)) in mine.nodes.iter().zip(&theirs.nodes).enumerate() {
                    if *partner.entry(a).or_insert(bn) != bn {
                        return Err(topology(format!(
                            "element {} differs in its connectivity",
                            k / mine.shape.n_nodes()
                        )));
                    }
                }
                let nodes: Vec<usize> = partner.keys().copied().collect();
                let velocity = partner
                    .iter()
                    .map(|(&a, &bn)| {
                        let d = xb[bn] * source.scale - x[a];
                        [d.x, d.y, d.z]
                    })
                    .collect();
                (nodes, MapKind::Velocity { velocity }, 0.0)
            }
            MapSpec::Boundary {
                surface,
                motion,
                fixed,
                slide,
                smoothing,
            } => {
                let b = body()?;
                let moved = node_set(surface, &format!("{at}.map.surface"))?;
                // the motion's direction, or its centre and axis, checked once
                enum Checked {
                    Along(nalgebra::Vector3<f64>),
                    Radial(nalgebra::Vector3<f64>, Option<nalgebra::Vector3<f64>>),
                }
                let checked = match motion {
                    SurfaceMotion::Translate { direction: d } => {
                        Checked::Along(direction(*d, &format!("{at}.map.motion.direction"))?)
                    }
                    SurfaceMotion::Radial { centre, axis } => Checked::Radial(
                        vec3(*centre, &format!("{at}.map.motion.centre"))?,
                        axis.map(|a| direction(a, &format!("{at}.map.motion.axis")))
                            .transpose()?,
                    ),
                };
                let mut prescribed = Vec::with_capacity(moved.len());
                for &n in &moved {
                    let v = match &checked {
                        Checked::Along(d) => (*d).into(),
                        Checked::Radial(c, axis) => {
                            let mut r = x[n] - c;
                            if let Some(a) = axis {
                                r -= a * a.dot(&r);
                            }
                            let len = r.norm();
                            if len.is_nan() || len <= 0.0 {
                                return Err(invalid(
                                    &format!("{at}.map.motion"),
                                    format!("node {n} of '{surface}' is on the centre (or axis): no radial direction"),
                                ));
                            }
                            (r / len).into()
                        }
                    };
                    prescribed.push((n, v));
                }
                let mut held = Vec::new();
                for (k, f) in fixed.iter().enumerate() {
                    for n in node_set(f, &format!("{at}.map.fixed[{k}]"))? {
                        held.extend([(n, 0), (n, 1), (n, 2)]);
                    }
                }
                for (k, (set, c)) in slide.iter().enumerate() {
                    for n in node_set(set, &format!("{at}.map.slide[{k}]"))? {
                        held.push((n, c.index()));
                    }
                }
                let (nodes, velocity) = crate::mesh::shape_map::boundary_driven(
                    &sh.name,
                    mesh,
                    &x,
                    b.group,
                    &prescribed,
                    &held,
                    *smoothing,
                )
                .map_err(bad)?;
                (nodes, MapKind::Velocity { velocity }, 0.0)
            }
        };
        let reference = sh.value.unwrap_or(reference);
        finite(reference, &format!("{at}.value"))?;
        ShapeMap::new(&sh.name, nodes, kind, reference).map_err(bad)
    }

    /// Validate and build the analysis model.
    pub fn build(&self) -> Result<Model, SceneError> {
        // sizes first: an absurd element count is an error, not an allocation attempt
        let mut total_elements: usize = 0;
        for (i, b) in self.bodies.iter().enumerate() {
            let at = format!("bodies[{i}]");
            let Some(block) = b.block() else {
                continue;
            };
            let mut n: usize = 1;
            let axes = [&block.x, &block.y, &block.z];
            for (c, (label, axis)) in ["x", "y", "z"].iter().zip(axes).enumerate() {
                let origin = block.origin[c];
                finite(origin, &format!("{at}.origin[{c}]"))?;
                n = n.saturating_mul(check_axis(axis, origin, &format!("{at}.{label}"))?);
            }
            check_aspect(&axes, block.element, &at)?;
            total_elements = total_elements.saturating_add(n);
            if total_elements > MAX_ELEMENTS {
                return Err(invalid(
                    &at,
                    format!("the bodies have more than {MAX_ELEMENTS} elements in all"),
                ));
            }
        }
        let mut mesh = Mesh::default();
        let mut bodies = Vec::new();
        for (i, b) in self.bodies.iter().enumerate() {
            let at = format!("bodies[{i}]");
            check_law(&b.material, &format!("{at}.material"))?;
            if bodies.iter().any(|o: &Body| o.name == b.name()) {
                return Err(invalid(
                    &format!("{at}.name"),
                    format!("a body named '{}' already exists", b.name()),
                ));
            }
            let group = match &b.geometry {
                BodyGeometry::Block(block) => {
                    let index = mesh
                        .add_block(block.clone())
                        .map_err(|e| invalid(&at, e.to_string()))?;
                    mesh.block_group(index)
                        .ok_or_else(|| invalid(&at, "the block made no element group"))?
                }
                BodyGeometry::Mesh(source) => self.add_mesh_body(&mut mesh, source, &at)?,
            };
            if mesh.n_elements() > MAX_ELEMENTS {
                return Err(invalid(
                    &at,
                    format!("the bodies have more than {MAX_ELEMENTS} elements in all"),
                ));
            }
            let body = Body {
                name: b.name().to_string(),
                group,
                material: b.material.clone(),
                kinematics: b.kinematics,
                formulation: b.formulation,
            };
            // a formulation the body's shape does not take (`reduced` on hex8, ...)
            body.family(&mesh)
                .map_err(|e| invalid(&format!("{at}.formulation"), e.to_string()))?;
            bodies.push(body);
        }
        for (i, f) in self.free_nodes.iter().enumerate() {
            for (c, v) in f.x.iter().enumerate() {
                finite(*v, &format!("free_nodes[{i}].x[{c}]"))?;
            }
            if mesh.node_sets.contains_key(&f.name) {
                return Err(invalid(
                    &format!("free_nodes[{i}].name"),
                    format!("set '{}' already exists", f.name),
                ));
            }
            let n = mesh.add_free_node(f.x);
            mesh.node_sets.insert(f.name.clone(), vec![n]);
        }
        self.add_intersections(&mut mesh)?;
        // the node sets are complete; the springs' element groups are still to be added
        let node_sets = mesh.node_sets.clone();
        let set = |name: &str, field: &str| -> Result<Vec<usize>, SceneError> {
            match node_sets.get(name) {
                Some(v) if !v.is_empty() => Ok(v.clone()),
                Some(_) => Err(invalid(field, format!("node set '{name}' is empty"))),
                None => Err(invalid(
                    field,
                    format!(
                        "no node set named '{name}' (sets: {})",
                        node_sets.keys().cloned().collect::<Vec<_>>().join(", ")
                    ),
                )),
            }
        };
        let one = |name: &str, field: &str| -> Result<usize, SceneError> {
            let v = set(name, field)?;
            if v.len() != 1 {
                return Err(invalid(
                    field,
                    format!("set '{name}' has {} nodes, a spring needs one", v.len()),
                ));
            }
            Ok(v[0])
        };
        let mut springs = Vec::new();
        for (i, s) in self.springs.iter().enumerate() {
            let at = format!("springs[{i}]");
            for r in s.stiffness.iter().flatten() {
                finite(*r, &format!("{at}.stiffness"))?;
            }
            // one group of one discrete element per spring, after every block's group
            let group = match &s.b {
                Some(b) => {
                    let nodes = vec![one(&s.a, &format!("{at}.a"))?, one(b, &format!("{at}.b"))?];
                    mesh.add_group(Shape::Line2, nodes)
                }
                None => mesh.add_group(Shape::Point1, vec![one(&s.a, &format!("{at}.a"))?]),
            }
            .map_err(|e| invalid(&at, e.to_string()))?;
            springs.push(SpringSet {
                name: at,
                group,
                stiffness: s.stiffness,
            });
        }
        let amplitude = |pts: &[(f64, f64)], field: &str| -> Result<Amplitude, SceneError> {
            if pts.is_empty() {
                return Err(invalid(field, "an amplitude needs at least one point"));
            }
            for (t, v) in pts {
                finite(*t, field)?;
                finite(*v, field)?;
            }
            if pts.windows(2).any(|w| w[1].0 < w[0].0) {
                return Err(invalid(field, "amplitude times must not decrease"));
            }
            Ok(Amplitude {
                points: pts.to_vec(),
            })
        };
        let mut prescribed = Vec::new();
        let mut seen = std::collections::HashMap::new();
        for (i, p) in self.prescribed.iter().enumerate() {
            let at = format!("prescribed[{i}]");
            finite(p.value, &format!("{at}.value"))?;
            let nodes = set(&p.set, &format!("{at}.set"))?;
            let amp = amplitude(&p.amplitude, &format!("{at}.amplitude"))?;
            if p.components.is_empty() {
                return Err(invalid(&format!("{at}.components"), "no component given"));
            }
            for c in &p.components {
                for &n in &nodes {
                    if let Some(j) = seen.insert((n, c.index()), i) {
                        return Err(invalid(
                            &at,
                            if j == i {
                                format!("component {c:?} is listed twice in '{}'", p.name)
                            } else {
                                format!(
                                    "node {n} component {c:?} is prescribed by both prescribed[{j}] ('{}') and prescribed[{i}] ('{}') (conflicting boundary conditions)",
                                    self.prescribed[j].name, p.name
                                )
                            },
                        ));
                    }
                }
                prescribed.push(Prescribed {
                    name: p.name.clone(),
                    nodes: nodes.clone(),
                    component: c.index(),
                    value: p.value,
                    amplitude: amp.clone(),
                });
            }
        }
        let mut loads = Vec::new();
        for (i, l) in self.loads.iter().enumerate() {
            let at = format!("loads[{i}]");
            finite(l.value, &format!("{at}.value"))?;
            let nodes = set(&l.set, &format!("{at}.set"))?;
            let weights = match mesh.face_sets.get(&l.set) {
                Some(faces) if !faces.is_empty() => {
                    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
                    let area = faces.tributary_areas(&x, &nodes);
                    let total: f64 = area.iter().sum();
                    if !(total.is_finite() && total > 0.0) {
                        return Err(invalid(
                            &format!("{at}.set"),
                            format!("the faces of '{}' have area {total}", l.set),
                        ));
                    }
                    area.iter().map(|a| a / total).collect()
                }
                _ => vec![1.0 / nodes.len() as f64; nodes.len()],
            };
            loads.push(NodalLoad {
                name: l.name.clone(),
                nodes,
                weights,
                component: l.component.index(),
                value: l.value,
                amplitude: amplitude(&l.amplitude, &format!("{at}.amplitude"))?,
            });
        }
        let mut pressures = Vec::new();
        for (i, p) in self.pressures.iter().enumerate() {
            let at = format!("pressures[{i}]");
            finite(p.value, &format!("{at}.value"))?;
            let faces = match mesh.face_sets.get(&p.faces) {
                Some(f) if !f.is_empty() => f.clone(),
                _ => {
                    return Err(invalid(
                        &format!("{at}.faces"),
                        format!(
                            "no face set named '{}' (face sets: {})",
                            p.faces,
                            mesh.face_sets
                                .keys()
                                .cloned()
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ))
                }
            };
            pressures.push(crate::load::PressureLoad {
                name: p.name.clone(),
                faces,
                value: p.value,
                amplitude: amplitude(&p.amplitude, &format!("{at}.amplitude"))?,
            });
        }
        for (i, sh) in self.shapes.iter().enumerate() {
            let map = self.shape_map(&mesh, &bodies, sh, &format!("shapes[{i}]"))?;
            mesh.shape_maps.push(map);
        }
        let mut times = Vec::new();
        let mut t0 = 0.0;
        if self.steps.is_empty() {
            return Err(invalid("steps", "no load step"));
        }
        for (i, s) in self.steps.iter().enumerate() {
            let at = format!("steps[{i}]");
            finite(s.end, &format!("{at}.end"))?;
            if s.end <= t0 {
                return Err(invalid(
                    &format!("{at}.end"),
                    format!(
                        "step ends at {} which is not after {t0} (zero or negative increment)",
                        s.end
                    ),
                ));
            }
            if s.increments == 0 {
                return Err(invalid(&format!("{at}.increments"), "must be at least 1"));
            }
            if s.increments > MAX_INCREMENTS - times.len() {
                return Err(invalid(
                    &format!("{at}.increments"),
                    format!("more than {MAX_INCREMENTS} increments in all steps"),
                ));
            }
            for k in 1..=s.increments {
                times.push(t0 + (s.end - t0) * k as f64 / s.increments as f64);
            }
            t0 = s.end;
        }
        let mut notes = Vec::new();
        let contacts = self.build_contacts(
            &mesh,
            &bodies,
            &springs,
            &prescribed,
            &amplitude,
            &mut notes,
        )?;
        let mut responses = Vec::new();
        let mut history_refs: Vec<(usize, usize, usize, usize, usize)> = Vec::new();
        for (i, r) in self.responses.iter().enumerate() {
            // the tables' columns and the sensitivity commands name a response by its name
            if self.responses[..i].iter().any(|o| o.name() == r.name()) {
                return Err(invalid(
                    &format!("responses[{i}].name"),
                    format!("a response named '{}' already exists", r.name()),
                ));
            }
            let field = format!("responses[{i}].set");
            let kind = match r {
                ResponseSpec::Reaction {
                    set: s, component, ..
                } => ResponseKind::Reaction {
                    nodes: set(s, &field)?,
                    component: component.index(),
                },
                ResponseSpec::Displacement {
                    set: s, component, ..
                } => ResponseKind::Displacement {
                    nodes: set(s, &field)?,
                    component: component.index(),
                },
                ResponseSpec::TargetForce {
                    pair, component, ..
                } => ResponseKind::TargetForce {
                    pair: contact_index(&contacts, pair, &format!("responses[{i}].pair"))?,
                    component: component.index(),
                },
                ResponseSpec::TargetDisplacement {
                    pair, component, ..
                } => {
                    let at = format!("responses[{i}].pair");
                    let p = contact_index(&contacts, pair, &at)?;
                    if !matches!(contacts[p].target, Target::Rigid { .. }) {
                        return Err(invalid(
                            &at,
                            format!("pair '{pair}' has no rigid target to follow"),
                        ));
                    }
                    ResponseKind::TargetDisplacement {
                        pair: p,
                        component: component.index(),
                    }
                }
                ResponseSpec::PressureProfile {
                    name,
                    pair,
                    along,
                    area,
                    per,
                } => {
                    let p = contact_index(&contacts, pair, &format!("responses[{i}].pair"))?;
                    let x = mesh.coordinates::<f64>(&mesh.block_geometry());
                    let c = &contacts[p];
                    let at = |i: usize| x[c.hitting[i]][along.index()];
                    let mut order: Vec<usize> = (0..c.hitting.len()).collect();
                    order.sort_by(|a, b| at(*a).total_cmp(&at(*b)));
                    // the corners of quadratic faces have no pressure area: no point of their
                    // own, and no station of corners alone
                    let share = c.pressure_areas_at(|n| x[n]);
                    let stations: Vec<Vec<usize>> = match per {
                        ProfilePoints::Node => (order.iter())
                            .filter(|i| share[**i] > 0.0)
                            .map(|i| vec![*i])
                            .collect(),
                        ProfilePoints::Station => {
                            let extent = match (order.first(), order.last()) {
                                (Some(a), Some(b)) => at(*b) - at(*a),
                                _ => 0.0,
                            };
                            let mut stations: Vec<Vec<usize>> = Vec::new();
                            for &i in &order {
                                match stations.last_mut() {
                                    Some(s) if at(i) - at(s[0]) <= 1e-9 * extent => s.push(i),
                                    _ => stations.push(vec![i]),
                                }
                            }
                            stations.retain(|s| s.iter().any(|i| share[*i] > 0.0));
                            stations
                        }
                    };
                    let prefix = match per {
                        ProfilePoints::Node => name.clone(),
                        ProfilePoints::Station if name.ends_with(area.name()) => name.clone(),
                        ProfilePoints::Station => format!("{name}_{}", area.name()),
                    };
                    for (k, nodes) in stations.into_iter().enumerate() {
                        responses.push(Response {
                            name: format!("{prefix}[{k}]"),
                            kind: ResponseKind::ContactPressure {
                                pair: p,
                                nodes,
                                measure: *area,
                            },
                        });
                    }
                    continue;
                }
                ResponseSpec::History {
                    body,
                    element,
                    point,
                    variable,
                    ..
                } => {
                    let at = format!("responses[{i}]");
                    let (bi, b) = bodies
                        .iter()
                        .enumerate()
                        .find(|(_, b)| &b.name == body)
                        .ok_or_else(|| {
                            invalid(&format!("{at}.body"), format!("no body '{body}'"))
                        })?;
                    let names = b.material.history_names();
                    let var = names.iter().position(|n| n == variable).ok_or_else(|| {
                        invalid(
                            &format!("{at}.variable"),
                            format!("material '{}' has history {names:?}", b.material.name()),
                        )
                    })?;
                    let elems = mesh.group_elements(b.group);
                    if *element >= elems.len() {
                        return Err(invalid(
                            &format!("{at}.element"),
                            format!("body '{body}' has {} elements", elems.len()),
                        ));
                    }
                    let n_gauss = b
                        .family(&mesh)
                        .map_err(|e| invalid(&format!("{at}.body"), format!("body '{body}': {e}")))?
                        .n_gauss();
                    if *point >= n_gauss {
                        return Err(invalid(
                            &format!("{at}.point"),
                            format!("Gauss points are 0-{}", n_gauss - 1),
                        ));
                    }
                    history_refs.push((responses.len(), bi, elems.start + element, *point, var));
                    ResponseKind::History { index: usize::MAX }
                }
                ResponseSpec::Stress {
                    body,
                    element,
                    measure,
                    ..
                } => {
                    let at = format!("responses[{i}]");
                    let b = bodies.iter().find(|b| &b.name == body).ok_or_else(|| {
                        invalid(&format!("{at}.body"), format!("no body '{body}'"))
                    })?;
                    let elems = mesh.group_elements(b.group);
                    if *element >= elems.len() {
                        return Err(invalid(
                            &format!("{at}.element"),
                            format!("body '{body}' has {} elements", elems.len()),
                        ));
                    }
                    ResponseKind::Stress {
                        element: elems.start + element,
                        measure: *measure,
                    }
                }
            };
            responses.push(Response {
                name: r.name().to_string(),
                kind,
            });
        }
        let sv = &self.solver;
        positive(sv.force_tol, "solver.force_tol")?;
        positive(sv.energy_tol, "solver.energy_tol")?;
        if sv.max_iterations == 0 {
            return Err(invalid("solver.max_iterations", "must be at least 1"));
        }
        if sv.max_cutbacks > MAX_CUTBACKS {
            return Err(invalid(
                "solver.max_cutbacks",
                format!("at most {MAX_CUTBACKS} halvings of an increment"),
            ));
        }
        let mut model = Model {
            mesh,
            bodies,
            springs,
            prescribed,
            loads,
            pressures,
            times,
            contacts,
            responses,
            solver: self.solver.clone(),
            notes,
            ..Model::default()
        };
        if !history_refs.is_empty() {
            let dofs = model.dof_map();
            for (r, b, e, point, var) in history_refs {
                let nh = model.bodies[b].material.history_len();
                model.responses[r].kind = ResponseKind::History {
                    index: dofs.history_offset[e] + point * nh + var,
                };
            }
        }
        if let Some(beta) = self.study.beta {
            finite(beta, "study.beta")?;
            if !(beta > 0.0 && beta < 1.0) {
                return Err(invalid(
                    "study.beta",
                    format!("must lie in (0, 1), got {beta}"),
                ));
            }
        }
        for (i, name) in self.study.params.iter().enumerate() {
            crate::design::Parameter::expand(&model, name)
                .map_err(|e| invalid(&format!("study.params[{i}]"), e.to_string()))?;
        }
        Ok(model)
    }
}

/// The nodes of a set expression: node sets, `node N` (mesh node number N, as in messages and
/// VTK files) and `near X Y Z` (the node nearest to the point in the reference configuration)
/// joined by `&` (intersection; `near` picks among the nodes of the other parts, or of the
/// whole mesh). `None` for a plain name (looked up, and reported if missing, by its user).
fn set_expression(
    name: &str,
    sets: &std::collections::BTreeMap<String, Vec<usize>>,
    x: &[nalgebra::Vector3<f64>],
) -> Result<Option<Vec<usize>>, String> {
    let parts: Vec<&str> = name.split('&').map(str::trim).collect();
    let special = |p: &str| p.starts_with("node ") || p.starts_with("near ");
    if parts.len() == 1 && !special(parts[0]) {
        return Ok(None);
    }
    let mut nodes: Option<Vec<usize>> = None;
    let mut near: Option<nalgebra::Vector3<f64>> = None;
    for part in &parts {
        let v: Vec<usize> = if let Some(id) = part.strip_prefix("node ") {
            let n: usize = id
                .trim()
                .parse()
                .map_err(|_| format!("'{part}': a node number, e.g. 'node 17'"))?;
            if n >= x.len() {
                return Err(format!(
                    "'{part}': the mesh has nodes 0 to {}",
                    x.len().saturating_sub(1)
                ));
            }
            vec![n]
        } else if let Some(at) = part.strip_prefix("near ") {
            let c: Vec<f64> = at
                .split(|ch: char| ch.is_whitespace() || ch == ',')
                .filter(|t| !t.is_empty())
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| format!("'{part}': three coordinates, e.g. 'near 20 0 0.25'"))?;
            if c.len() != 3 || c.iter().any(|v| !v.is_finite()) {
                return Err(format!(
                    "'{part}': three coordinates, e.g. 'near 20 0 0.25'"
                ));
            }
            near = Some(nalgebra::Vector3::new(c[0], c[1], c[2]));
            continue;
        } else {
            sets.get(*part)
                .cloned()
                .ok_or_else(|| format!("no node set named '{part}' (in '{name}')"))?
        };
        nodes = Some(match nodes {
            None => v,
            Some(n) => n.into_iter().filter(|k| v.contains(k)).collect(),
        });
    }
    let mut nodes = nodes.unwrap_or_else(|| (0..x.len()).collect());
    if let Some(p) = near {
        let d = |n: usize| (x[n] - p).norm();
        let best = nodes.iter().copied().min_by(|a, b| d(*a).total_cmp(&d(*b)));
        let Some(best) = best else {
            return Err(format!("'{name}': no node to pick from"));
        };
        // two nodes at one place (the two bodies' nodes at a contact point): say which
        let tied: Vec<usize> = (nodes.iter().copied())
            .filter(|n| *n != best && (x[*n] - x[best]).norm() <= 1e-12 * (1.0 + x[best].norm()))
            .collect();
        if !tied.is_empty() {
            return Err(format!(
                "'{name}': nodes {best} and {} are both nearest (at one place); intersect with a body's set, e.g. 'BODY.all & near ...'",
                tied[0]
            ));
        }
        nodes = vec![best];
    }
    if nodes.is_empty() {
        return Err(format!("the intersection '{name}' is empty"));
    }
    Ok(Some(nodes))
}

/// A mesh path as given in a scene: relative to the scene file's folder (or the working
/// folder when the scene was not read from a file).
fn resolve(folder: Option<&std::path::Path>, file: &std::path::Path) -> std::path::PathBuf {
    match folder {
        Some(dir) if file.is_relative() => dir.join(file),
        _ => file.to_path_buf(),
    }
}

/// Largest number of elements of a scene (all bodies).
const MAX_ELEMENTS: usize = 10_000_000;
/// Largest number of elements along one axis of a block.
const MAX_AXIS_ELEMENTS: usize = 100_000;
/// Largest number of load increments of a scene (all steps).
const MAX_INCREMENTS: usize = 1_000_000;
/// Largest number of halvings of an increment.
const MAX_CUTBACKS: usize = 64;

/// Checks one axis of a block (`at` is its TOML path, `origin` the block's origin along it)
/// and returns its number of elements.
fn check_axis(axis: &Axis, origin: f64, at: &str) -> Result<usize, SceneError> {
    positive(axis.length, &format!("{at}.length"))?;
    if !(origin + axis.length).is_finite() {
        return Err(invalid(
            &format!("{at}.length"),
            format!(
                "the block reaches {origin} + {} beyond the f64 range",
                axis.length
            ),
        ));
    }
    if axis.zones.is_empty() {
        return Err(invalid(
            &format!("{at}.zones"),
            "an axis needs at least one zone",
        ));
    }
    let mut n: usize = 0;
    for (k, z) in axis.zones.iter().enumerate() {
        let zf = format!("{at}.zones[{k}]");
        positive(z.fraction, &format!("{zf}.fraction"))?;
        positive(z.ratio, &format!("{zf}.ratio"))?;
        if z.elements == 0 {
            return Err(invalid(&format!("{zf}.elements"), "must be at least 1"));
        }
        n = n
            .checked_add(z.elements)
            .filter(|n| *n <= MAX_AXIS_ELEMENTS)
            .ok_or_else(|| {
                invalid(
                    &format!("{zf}.elements"),
                    format!("more than {MAX_AXIS_ELEMENTS} elements along one axis"),
                )
            })?;
    }
    // the grading must give elements of positive size in f64
    let t = axis.fractions();
    if t.iter().any(|v| !v.is_finite()) || t.windows(2).any(|w| w[1] <= w[0]) {
        return Err(invalid(
            &format!("{at}.zones"),
            "the fractions and ratios give elements of zero or non-finite size",
        ));
    }
    Ok(n)
}

/// Checks a block's grading against its thinnest element faces: a block's elements take
/// every combination of the axes' element sizes, so its thinnest face along axis `c` has the
/// sides `min_c` and `max_a`, the largest element size along another axis `a`. The contact
/// geometry refuses a face whose centre Jacobian is below
/// [`crate::contact::geometry::AREA_TOLERANCE`] times its diagonal squared: a quad's is a
/// quarter of its sides' product, a right triangle's the product, so a block of hexahedra is
/// refused below `min_c / max_a = 4 AREA_TOLERANCE` and one with triangular faces (tetrahedra,
/// wedges) below `AREA_TOLERANCE`, its elements collapsed too (a zone `ratio` of 1e12 made
/// one). The axes are checked ([`check_axis`]) before.
fn check_aspect(axes: &[&Axis; 3], shape: Shape, at: &str) -> Result<(), SceneError> {
    let each = axes.map(|a| {
        (a.element_sizes().into_iter()).fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
    });
    let quads = matches!(shape, Shape::Hex8 | Shape::Hex20);
    let floor = if quads { 4.0 } else { 1.0 } * crate::contact::geometry::AREA_TOLERANCE;
    for c in 0..3 {
        let (thinnest, _) = each[c];
        let across = (0..3)
            .filter(|&a| a != c)
            .fold(0.0f64, |m, a| m.max(each[a].1));
        if thinnest < floor * across {
            let axis = axes[c];
            let uniform = axis.zones.len() == 1 && axis.zones[0].ratio == 1.0;
            let label = ["x", "y", "z"][c];
            return Err(invalid(
                &format!("{at}.{label}.{}", if uniform { "length" } else { "zones" }),
                format!(
                    "elements {thinnest:.3e} thin along {label} against {across:.3e} across, below {floor:e} of it: their faces are degenerate to the contact search and their Jacobians collapsed"
                ),
            ));
        }
    }
    Ok(())
}

/// Factor `c_T` of the default tangential penalty (see [`setup::TANGENTIAL_STIFFNESS_FACTOR`]).
pub const TANGENTIAL_STIFFNESS_FACTOR: f64 = setup::TANGENTIAL_STIFFNESS_FACTOR;

/// Validates and builds an amplitude, naming the field in errors.
type AmplitudeBuilder<'a> = dyn Fn(&[(f64, f64)], &str) -> Result<Amplitude, SceneError> + 'a;

fn contact_index(contacts: &[ContactPair], name: &str, field: &str) -> Result<usize, SceneError> {
    contacts.iter().position(|c| c.name == name).ok_or_else(|| {
        invalid(
            field,
            format!(
                "no contact pair '{name}' (pairs: {})",
                contacts
                    .iter()
                    .map(|c| c.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )
    })
}

fn vec3(v: [f64; 3], field: &str) -> Result<nalgebra::Vector3<f64>, SceneError> {
    for x in v {
        finite(x, field)?;
    }
    Ok(nalgebra::Vector3::from(v))
}

/// A direction: finite, with a finite nonzero length.
fn direction(v: [f64; 3], field: &str) -> Result<nalgebra::Vector3<f64>, SceneError> {
    let d = vec3(v, field)?;
    let n = d.norm();
    if !(n.is_finite() && n > 0.0) {
        return Err(invalid(
            field,
            format!("a direction needs a finite nonzero length, got {v:?}"),
        ));
    }
    Ok(d)
}

impl Scene {
    fn build_contacts(
        &self,
        mesh: &Mesh,
        bodies: &[Body],
        springs: &[SpringSet],
        prescribed: &[Prescribed],
        amplitude: &AmplitudeBuilder<'_>,
        notes: &mut Vec<String>,
    ) -> Result<Vec<ContactPair>, SceneError> {
        let x = mesh.coordinates::<f64>(&mesh.block_geometry());
        let node_group = setup::node_groups(mesh);
        let mut out = Vec::new();
        for (ci, c) in self.contacts.iter().enumerate() {
            let at = format!("contacts[{ci}]");
            if self.contacts[..ci].iter().any(|o| o.name == c.name) {
                return Err(invalid(
                    &format!("{at}.name"),
                    format!("pair '{}' defined twice", c.name),
                ));
            }
            // hitting nodes and their tributary areas
            // per hitting node: tributary area, and the stiffness A_i / h_i of the element
            // layer under it (none for a node set)
            let (hitting, area, layer, hitting_faces) =
                if let Some(faces) = mesh.face_sets.get(&c.hitting) {
                    let nodes = setup::face_set_nodes(faces);
                    let area = faces.tributary_areas(&x, &nodes);
                    let layer = setup::layer_stiffness(mesh, &x, faces, &nodes, &area);
                    (nodes, area, layer, Some(faces.clone()))
                } else if let Some(nodes) = mesh.node_sets.get(&c.hitting) {
                    if nodes.is_empty() {
                        return Err(invalid(
                            &format!("{at}.hitting"),
                            format!("node set '{}' is empty", c.hitting),
                        ));
                    }
                    (nodes.clone(), vec![1.0; nodes.len()], None, None)
                } else {
                    return Err(invalid(
                        &format!("{at}.hitting"),
                        format!("no face set or node set named '{}'", c.hitting),
                    ));
                };
            if let Some(r) = c.search_radius {
                positive(r, &format!("{at}.search_radius"))?;
            }
            let (target, candidates, diag) = match &c.target {
                TargetSpec::Faces(name) => {
                    let faces = mesh.face_sets.get(name).ok_or_else(|| {
                        invalid(
                            &format!("{at}.target"),
                            format!("no face set named '{name}'"),
                        )
                    })?;
                    if faces.is_empty() {
                        return Err(invalid(
                            &format!("{at}.target"),
                            format!("face set '{name}' is empty"),
                        ));
                    }
                    // default: three face diagonals, plus how far the prescribed
                    // displacements can move the two bodies against each other
                    let (default, diag, travel) = setup::default_search_radius(
                        &x,
                        &node_group,
                        prescribed,
                        hitting[0],
                        faces,
                    );
                    let radius = match c.search_radius {
                        Some(r) => r,
                        None => {
                            let r = default;
                            notes.push(format!(
                                "{at} '{}': search radius {r:.4e} (3 face diagonals {:.4e} + the bodies' largest prescribed travel {travel:.4e})",
                                c.name,
                                3.0 * diag
                            ));
                            r
                        }
                    };
                    positive(radius, &format!("{at}.search_radius"))?;
                    let candidates = setup::candidates(&x, faces, &hitting, radius);
                    (
                        Target::Faces {
                            faces: faces.clone(),
                        },
                        candidates,
                        diag,
                    )
                }
                TargetSpec::Rigid { surface, motion } => {
                    let sf = format!("{at}.target.surface");
                    let surface = match surface {
                        RigidSpec::Plane { point, normal } => RigidSurface::Plane {
                            point: vec3(*point, &format!("{sf}.point"))?,
                            normal: direction(*normal, &format!("{sf}.normal"))?,
                        },
                        RigidSpec::Cylinder {
                            axis_point,
                            axis,
                            radius,
                        } => {
                            positive(*radius, &format!("{sf}.radius"))?;
                            RigidSurface::Cylinder {
                                axis_point: vec3(*axis_point, &format!("{sf}.axis_point"))?,
                                axis: direction(*axis, &format!("{sf}.axis"))?,
                                radius: *radius,
                            }
                        }
                        RigidSpec::RoundedBox {
                            center,
                            half_extents,
                            radius,
                        } => {
                            for h in half_extents {
                                positive(*h, &format!("{sf}.half_extents"))?;
                            }
                            finite(*radius, &format!("{sf}.radius"))?;
                            if *radius < 0.0 || half_extents.iter().any(|h| *radius > *h) {
                                return Err(invalid(
                                    &format!("{sf}.radius"),
                                    "needs 0 <= radius <= every half extent",
                                ));
                            }
                            RigidSurface::RoundedBox {
                                center: vec3(*center, &format!("{sf}.center"))?,
                                half_extents: vec3(*half_extents, &sf)?,
                                radius: *radius,
                            }
                        }
                    };
                    let mut m: Vec<RigidMotion> = Vec::new();
                    for (k, ms) in motion.iter().enumerate() {
                        let f = format!("{at}.target.motion[{k}]");
                        let (value, control) = match (ms.value, ms.force) {
                            (Some(v), None) => (v, MotionControl::Displacement),
                            (None, Some(v)) => (v, MotionControl::Force),
                            _ => {
                                return Err(invalid(
                                    &f,
                                    "give exactly one of `value` (a translation) and `force`",
                                ))
                            }
                        };
                        let field = match control {
                            MotionControl::Displacement => "value",
                            MotionControl::Force => "force",
                        };
                        finite(value, &format!("{f}.{field}"))?;
                        let component = ms.component.index();
                        // a pushed component is one unknown: no second force, and no
                        // translation beside it
                        if let Some(j) = m.iter().position(|o| {
                            o.component == component
                                && (o.control == MotionControl::Force
                                    || control == MotionControl::Force)
                        }) {
                            return Err(invalid(
                                &format!("{f}.component"),
                                format!(
                                    "motion[{j}] already moves component {} and one of them is \
                                     a force: a pushed component takes one force and no \
                                     prescribed translation",
                                    ["x", "y", "z"][component]
                                ),
                            ));
                        }
                        m.push(RigidMotion {
                            component,
                            value,
                            amplitude: amplitude(&ms.amplitude, &format!("{f}.amplitude"))?,
                            control,
                        });
                    }
                    (
                        Target::Rigid { surface, motion: m },
                        vec![Vec::new(); hitting.len()],
                        0.0,
                    )
                }
            };
            // hitting nodes with no target face within the search radius can never touch it:
            // left out of the pair (all of them: an error)
            let (hitting, area, layer, candidates) = if let Target::Faces { .. } = target {
                let r = setup::keep_reachable(&hitting, &area, layer.as_deref(), candidates);
                let dropped = r.dropped;
                if r.hitting.is_empty() {
                    return Err(invalid(
                        &format!("{at}.search_radius"),
                        format!(
                            "no target face is within the search radius of any hitting node (largest face diagonal {diag:.3e}): the pair can never touch"
                        ),
                    ));
                }
                if !dropped.is_empty() {
                    let shown: Vec<String> =
                        dropped.iter().take(8).map(|n| n.to_string()).collect();
                    notes.push(format!(
                        "{at} '{}': {} of {} hitting nodes have no target face within the search radius and are left out (they can never touch it): nodes {}{}",
                        c.name,
                        dropped.len(),
                        hitting.len(),
                        shown.join(", "),
                        if dropped.len() > 8 { ", ..." } else { "" }
                    ));
                }
                (r.hitting, r.area, r.layer, r.candidates)
            } else {
                (hitting, area, layer, candidates)
            };
            // a node meets a target through one Lagrange pair: two multipliers of the same
            // node and target impose one constraint twice and make the tangent singular (a
            // pair copied under another name). Penalty and augmented-Lagrangian pairs may
            // share a node (a surface split into two face sets along an edge: each pair
            // takes its faces' share of the node's area). The nodes compared are those that
            // can reach the target (above).
            for ((cj, o), earlier) in self.contacts[..ci].iter().enumerate().zip(&out) {
                let earlier: &ContactPair = earlier;
                let lagrange = |law: &NormalLaw| matches!(law, NormalLaw::Lagrange);
                if o.target != c.target || !(lagrange(&o.normal) && lagrange(&c.normal)) {
                    continue;
                }
                let theirs: std::collections::BTreeSet<usize> =
                    earlier.hitting.iter().copied().collect();
                if let Some(n) = hitting.iter().find(|n| theirs.contains(n)) {
                    return Err(invalid(
                        &format!("{at}.hitting"),
                        format!(
                            "node {n} of '{}' already meets the same target through contacts[{cj}] ('{}'), both with Lagrange multipliers: one constraint imposed twice makes the tangent singular",
                            c.hitting, o.name
                        ),
                    ));
                }
            }
            if let Some(f) = &c.friction {
                check_law(f, &format!("{at}.friction"))?;
            }
            let friction = c.friction.clone();
            match c.normal {
                NormalLaw::Penalty { stiffness } => {
                    positive(stiffness, &format!("{at}.normal.stiffness"))?;
                }
                NormalLaw::Augmented {
                    stiffness,
                    tolerance,
                } => {
                    positive(stiffness, &format!("{at}.normal.stiffness"))?;
                    positive(tolerance, &format!("{at}.normal.tolerance"))?;
                }
                NormalLaw::Lagrange => {}
            }
            let scale = match c.constraint_scale {
                Some(k) => {
                    positive(k, &format!("{at}.constraint_scale"))?;
                    k
                }
                None => {
                    let (k, source) = setup::default_constraint_scale(bodies, springs, &area);
                    if c.normal == NormalLaw::Lagrange {
                        notes.push(format!(
                            "{at} '{}': constraint scale {k:.4e} (force per unit gap of the multiplier rows: {})",
                            c.name,
                            if source == setup::ScaleSource::Modulus {
                                "the largest E times the square root of the mean tributary area"
                            } else {
                                "the largest spring stiffness"
                            }
                        ));
                    }
                    k
                }
            };
            let activation = match c.activation {
                Some(a) => {
                    positive(a, &format!("{at}.activation"))?;
                    a
                }
                None => 1.0,
            };
            // the tangential penalty: given, or derived per node from the element layer
            // under it (TANGENTIAL_STIFFNESS_FACTOR E* A_i / h_i)
            let (eps_t, weight) = match (c.tangential_stiffness, &layer) {
                (Some(k), _) => {
                    positive(k, &format!("{at}.tangential_stiffness"))?;
                    (k, vec![1.0; hitting.len()])
                }
                (None, Some(layer)) => {
                    let target_node = match &target {
                        Target::Faces { faces } => Some(faces.nodes(0)[0]),
                        Target::Rigid { .. } => None,
                    };
                    let e_star =
                        setup::contact_modulus(&node_group, bodies, hitting[0], target_node);
                    let t = setup::default_tangential(e_star, layer);
                    let mean = t.mean;
                    if !(mean.is_finite() && mean > 0.0) {
                        return Err(invalid(
                            &format!("{at}.tangential_stiffness"),
                            format!("no default from the surface elements (mean stiffness {mean}): give one"),
                        ));
                    }
                    let (lo, hi) = t
                        .per_node
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(a, b), k| (a.min(*k), b.max(*k)));
                    notes.push(format!(
                        "{at} '{}': tangential stiffness {mean:.4e} per hitting node on average ({lo:.4e} to {hi:.4e}): {} E* A_i / h_i, with E* = {e_star:.4e} and A_i / h_i the node's area over the thickness of the element layer under it",
                        c.name,
                        TANGENTIAL_STIFFNESS_FACTOR
                    ));
                    (mean, t.weight)
                }
                (None, None) => (100.0 * scale, vec![1.0; hitting.len()]),
            };
            let smoothing = match (&target, c.smoothing) {
                (Target::Faces { faces }, choice) => {
                    let linear = !faces.has_quadratic();
                    match choice {
                        Some(Smoothing::Normals) if !linear => {
                            return Err(invalid(
                                &format!("{at}.smoothing"),
                                "smoothed normals need linear target faces (quad4, tri3); a quadratic face is curved already".to_string(),
                            ))
                        }
                        Some(choice) => choice == Smoothing::Normals,
                        None => {
                            notes.push(if linear {
                                format!("{at} '{}': smoothed normals (the hitting nodes projected along the target's averaged nodal normals: gap and normal continuous from face to face; edges sharper than 60 degrees kept sharp)", c.name)
                            } else {
                                format!("{at} '{}': no smoothing (quadratic target faces, curved already)", c.name)
                            });
                            linear
                        }
                    }
                }
                (Target::Rigid { .. }, Some(Smoothing::Normals)) => {
                    return Err(invalid(
                        &format!("{at}.smoothing"),
                        "a rigid target's surface is smooth already: smoothing is for face targets"
                            .to_string(),
                    ))
                }
                (Target::Rigid { .. }, _) => false,
            };
            out.push(ContactPair {
                name: c.name.clone(),
                hitting,
                area,
                hitting_faces,
                target,
                normal: c.normal,
                friction,
                tangential_stiffness: eps_t,
                tangential_weight: weight,
                constraint_scale: scale,
                activation,
                candidates,
                smoothing,
            });
        }
        Ok(out)
    }
}
