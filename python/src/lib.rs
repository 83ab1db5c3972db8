//! `fricsens._fricsens`: the Rust side of the Python package.
//!
//! It stays thin: a scene (built-in, a TOML file or TOML text) with design-parameter values
//! set on it, and two runs, the primal analysis and a sensitivity analysis by any method,
//! whose results go back as flat lists with their shapes (the Python side makes NumPy arrays
//! of them, exactly: an f64 becomes a Python float without rounding) and JSON for the
//! records (kinks, the cost ledger). Every run releases the GIL; a progress callback, if
//! given, is called with the GIL taken again after each converged increment.

use fricsens::model::{node_dofs, Model};
use fricsens::prelude::*;
use fricsens::sensitivity::{
    run_inline_keeping, run_sensitivity_watched, SensitivityResults, TangentChoice,
};
use fricsens::solver::Results;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    _fricsens,
    FricsensError,
    PyException,
    "Base of every fricsens error."
);
create_exception!(
    _fricsens,
    SceneError,
    FricsensError,
    "A scene that cannot be read or built (the message names the file, line and field)."
);
create_exception!(
    _fricsens,
    ParameterError,
    FricsensError,
    "A design parameter the scene does not have, or a bad value for it."
);
create_exception!(
    _fricsens,
    AnalysisError,
    FricsensError,
    "An analysis that stopped (the message names the increment and what failed)."
);

fn scene_err(e: impl std::fmt::Display) -> PyErr {
    SceneError::new_err(e.to_string())
}

/// `AnalysisError` for scene `name`, with `partial` (what the call returns, for the
/// increments that converged; `None` where none did) as its attribute `partial` (else the
/// class's `None`).
fn analysis_err(
    py: Python<'_>,
    name: &str,
    e: &fricsens::solver::AnalysisError,
    partial: Option<Bound<'_, PyDict>>,
) -> PyErr {
    let err = AnalysisError::new_err(format!("{name}: {e}"));
    if let Some(p) = partial {
        if let Err(x) = err.value(py).setattr("partial", p) {
            return x;
        }
    }
    err
}

/// A scene with design-parameter values set on it.
#[pyclass(module = "fricsens._fricsens", name = "Scene")]
#[derive(Clone)]
struct PyScene {
    scene: Scene,
    /// `(parameter name, value)` set after building, in order.
    values: Vec<(String, f64)>,
}

impl PyScene {
    /// The model with the set values.
    fn model(&self) -> PyResult<Model> {
        let mut model = self.scene.build().map_err(scene_err)?;
        for (name, v) in &self.values {
            let p = Parameter::by_name(&model, name)
                .map_err(|e| ParameterError::new_err(e.to_string()))?;
            for t in &p.targets {
                model.set_param(*t, *v);
            }
        }
        Ok(model)
    }

    fn params(model: &Model, names: &[String]) -> PyResult<Vec<Parameter>> {
        let mut out = Vec::new();
        for n in names {
            out.extend(
                Parameter::expand(model, n).map_err(|e| ParameterError::new_err(e.to_string()))?,
            );
        }
        Ok(out)
    }
}

/// Call `progress(increment, time)` with the GIL; a Python error in it is printed, not raised
/// (the analysis goes on).
fn report(progress: &Option<PyObject>, index: usize, time: f64) {
    if let Some(cb) = progress {
        Python::with_gil(|py| {
            if let Err(e) = cb.call1(py, (index, time)) {
                e.print(py);
            }
        });
    }
}

struct Progress<'a>(&'a Option<PyObject>);

impl Observer for Progress<'_> {
    fn converged(&mut self, c: &Converged<'_>) -> Result<(), fricsens::solver::AnalysisError> {
        report(self.0, c.index, c.time);
        Ok(())
    }
}

#[pymethods]
impl PyScene {
    /// A built-in scene by name (`builtin_scenes()` lists them), or a TOML file by path.
    #[staticmethod]
    fn load(name_or_path: &str) -> PyResult<Self> {
        let scene = Scene::load(name_or_path).map_err(scene_err)?;
        Ok(PyScene {
            scene,
            values: Vec::new(),
        })
    }

    /// A scene from TOML text (`source` names it in error messages).
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_toml(text: &str, source: &str) -> PyResult<Self> {
        let scene = Scene::from_toml(text, source).map_err(scene_err)?;
        scene.build().map_err(scene_err)?;
        Ok(PyScene {
            scene,
            values: Vec::new(),
        })
    }

    /// The scene's name.
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// The scene as TOML (the values set with `set` are not in it).
    fn to_toml(&self) -> PyResult<String> {
        self.scene.to_toml().map_err(scene_err)
    }

    /// The parameters the scene's study declares.
    #[getter]
    fn study_parameters(&self) -> Vec<String> {
        self.scene.study.params.clone()
    }

    /// The study's relative perturbation for SDM and FDM.
    #[getter]
    fn study_beta(&self) -> f64 {
        self.scene.study.beta()
    }

    /// The pseudo-times that end the scene's increments (the solver may add cut-back
    /// sub-increments between them).
    #[getter]
    fn times(&self) -> PyResult<Vec<f64>> {
        Ok(self.model()?.times)
    }

    /// The response names, in the order of the result columns.
    #[getter]
    fn responses(&self) -> PyResult<Vec<String>> {
        Ok(self
            .model()?
            .responses
            .iter()
            .map(|r| r.name.clone())
            .collect())
    }

    /// The current value of a design parameter (`mu`, `E`, `upper.length.x`, ...).
    fn get(&self, name: &str) -> PyResult<f64> {
        let model = self.model()?;
        Parameter::by_name(&model, name)
            .map(|p| p.value)
            .map_err(|e| ParameterError::new_err(e.to_string()))
    }

    /// A copy with design parameter `name` set to `value` (checked by building the model and
    /// checking its materials' and friction laws' parameters).
    fn with_value(&self, name: &str, value: f64) -> PyResult<Self> {
        let mut s = self.clone();
        s.values.push((name.to_string(), value));
        let model = s.model()?;
        model
            .check_laws()
            .map_err(|e| ParameterError::new_err(format!("{name} = {value}: {e}")))?;
        Ok(s)
    }

    /// The primal analysis. Returns a dict of flat lists and shapes (`fricsens.run` makes the
    /// arrays).
    #[pyo3(signature = (progress = None))]
    fn run<'py>(
        &self,
        py: Python<'py>,
        progress: Option<PyObject>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let model = self.model()?;
        let res = py.allow_threads(|| {
            let mut solver = Solver::new(&model)?;
            solver.run(&RunOptions::default(), &mut Progress(&progress))
        });
        match res {
            Ok(res) => run_dict(py, &model, &res),
            Err(e) => {
                // index 0 is the initial state: a partial run has a converged increment more
                let partial = e
                    .partial()
                    .filter(|p| p.states.len() > 1)
                    .map(|p| run_dict(py, &model, p))
                    .transpose()?;
                Err(analysis_err(py, &self.scene.name, &e, partial))
            }
        }
    }

    /// A sensitivity analysis of every response with respect to `params` by `method` (`ddm`,
    /// `sdm`, `sdm-central`, `fdm`, `fdm-central`); `beta` a relative step, `"auto"` (SDM, FDM), or
    /// `None` for the study's; `tangent` `exact`, `last` or `refined`; `fields` keeps the
    /// derivatives of the displacement field; `rigid_modes` the refined SDM for shape
    /// parameters (`--rigid-modes`).
    #[pyo3(signature = (params, method = "ddm", beta = None, tangent = "exact", fields = false, rigid_modes = false, progress = None))]
    #[allow(clippy::too_many_arguments)]
    fn sensitivity<'py>(
        &self,
        py: Python<'py>,
        params: Vec<String>,
        method: &str,
        beta: Option<Bound<'py, PyAny>>,
        tangent: &str,
        fields: bool,
        rigid_modes: bool,
        progress: Option<PyObject>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let model = self.model()?;
        let method = Method::ALL
            .into_iter()
            .find(|m| m.name() == method)
            .ok_or_else(|| {
                FricsensError::new_err(format!(
                    "method `{method}`: one of ddm, sdm, sdm-central, fdm, fdm-central, adjoint"
                ))
            })?;
        let tangent = match tangent {
            "exact" => TangentChoice::Exact,
            "last" => TangentChoice::Last,
            "refined" => TangentChoice::Refined,
            t => {
                return Err(FricsensError::new_err(format!(
                    "tangent `{t}`: one of exact, last, refined"
                )))
            }
        };
        let (beta, beta_auto) = match &beta {
            None => (self.scene.study.beta(), false),
            Some(b) => match b.extract::<f64>() {
                Ok(v) => (v, false),
                Err(_) if b.extract::<String>().is_ok_and(|s| s == "auto") => {
                    (self.scene.study.beta(), true)
                }
                Err(_) => {
                    return Err(FricsensError::new_err(
                        "beta takes a number, \"auto\" or None",
                    ))
                }
            },
        };
        if !(beta > 0.0 && beta < 1.0) {
            return Err(FricsensError::new_err(format!(
                "beta must lie in (0, 1), got {beta}"
            )));
        }
        if beta_auto && !method.uses_beta() {
            return Err(FricsensError::new_err(
                "beta=\"auto\" chooses the step of a difference: use it with method sdm, sdm-central, fdm or fdm-central",
            ));
        }
        if rigid_modes && !matches!(method, Method::Sdm | Method::SdmCentral) {
            return Err(FricsensError::new_err(
                "rigid_modes=True refines SDM's difference: use it with method sdm or sdm-central",
            ));
        }
        if fields && method == Method::Adjoint {
            return Err(FricsensError::new_err(
                "fields=True: the adjoint's field derivatives are not built yet",
            ));
        }
        let ps = Self::params(&model, &params)?;
        let settings = Settings {
            method,
            beta,
            tangent,
            beta_auto,
            fields,
            rigid_modes,
            ..Settings::default()
        };
        let run = py.allow_threads(|| {
            if method.is_inline() {
                run_inline_keeping(&model, &ps, &settings, &mut |c| {
                    report(&progress, c.index, c.time)
                })
                .map_err(|b| {
                    let (e, partial) = *b;
                    Box::new((e, Some(partial)))
                })
            } else {
                // finite differences need the reruns of the whole history, and the adjoint's
                // backward sweep starts at the last increment: no partial sensitivities
                run_sensitivity_watched(&model, &ps, &settings, &mut |c| {
                    report(&progress, c.index, c.time)
                })
                .map_err(|e| Box::new((e, None)))
            }
        });
        let sens_out = |sens: &SensitivityResults, primal_wall: f64| {
            sensitivity_dict(py, &model, sens, primal_wall, beta, fields, ps.len())
        };
        match run {
            Ok((res, sens)) => sens_out(&sens, res.cost.wall_seconds),
            Err(b) => {
                let (e, partial) = *b;
                let primal_wall = e.partial().map_or(f64::NAN, |p| p.cost.wall_seconds);
                let partial = partial
                    .filter(|sens| !sens.increments.is_empty())
                    .map(|sens| sens_out(&sens, primal_wall))
                    .transpose()?;
                Err(analysis_err(py, &self.scene.name, &e, partial))
            }
        }
    }
}

/// What `Scene.sensitivity` returns: flat lists with their shapes, JSON for the records.
fn sensitivity_dict<'py>(
    py: Python<'py>,
    model: &Model,
    sens: &SensitivityResults,
    primal_wall: f64,
    beta: f64,
    fields: bool,
    n_params: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let method = sens.method.unwrap_or(Method::Ddm);
    let out = PyDict::new(py);
    out.set_item("method", method.name())?;
    out.set_item(
        "beta",
        if method == Method::Ddm {
            None
        } else {
            Some(beta)
        },
    )?;
    out.set_item("parameters", sens.parameters.clone())?;
    out.set_item("responses", sens.responses.clone())?;
    out.set_item(
        "increments",
        sens.increments
            .iter()
            .map(|i| i.increment)
            .collect::<Vec<_>>(),
    )?;
    out.set_item(
        "times",
        sens.increments.iter().map(|i| i.time).collect::<Vec<_>>(),
    )?;
    let values: Vec<f64> = sens
        .increments
        .iter()
        .flat_map(|i| i.values.clone())
        .collect();
    out.set_item("values", values)?;
    let derivatives: Vec<f64> = (sens.increments.iter())
        .flat_map(|i| i.derivatives.iter().flatten().copied())
        .collect();
    out.set_item("derivatives", derivatives)?;
    let bars: Vec<f64> = (sens.increments.iter())
        .flat_map(|i| i.error_bars.iter().flatten().copied())
        .collect();
    out.set_item("error_bars", bars)?;
    let betas: Vec<f64> = sens
        .increments
        .iter()
        .flat_map(|i| i.betas.clone())
        .collect();
    out.set_item("betas", betas)?;
    let kinks: Vec<_> = sens.increments.iter().map(|i| &i.kinks).collect();
    out.set_item("kinks", serde_json::to_string(&kinks).expect("serialises"))?;
    let one_sided: Vec<_> = sens.increments.iter().map(|i| &i.one_sided).collect();
    out.set_item(
        "one_sided",
        serde_json::to_string(&one_sided).expect("serialises"),
    )?;
    out.set_item(
        "cost",
        serde_json::to_string(&sens.cost).expect("serialises"),
    )?;
    out.set_item("primal_seconds", sens.primal_seconds)?;
    out.set_item("primal_wall_seconds", primal_wall)?;
    out.set_item("n_nodes", model.mesh.n_nodes())?;
    if fields {
        let n = model.mesh.n_nodes();
        let mut d = Vec::with_capacity(sens.fields.len() * n_params * 3 * n);
        for f in &sens.fields {
            for p in &f.derivatives {
                match p.iter().find(|f| f.name == "displacement") {
                    Some(u) => d.extend_from_slice(&u.values),
                    None => d.extend(std::iter::repeat_n(f64::NAN, 3 * n)),
                }
            }
        }
        out.set_item("displacement_derivatives", d)?;
    }
    Ok(out)
}

/// What `Scene.run` returns for the results `res` of `model`: flat lists with their shapes.
fn run_dict<'py>(py: Python<'py>, model: &Model, res: &Results) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    let stored = res.states.len();
    out.set_item("times", res.times[..stored].to_vec())?;
    out.set_item(
        "responses",
        model
            .responses
            .iter()
            .map(|r| r.name.clone())
            .collect::<Vec<_>>(),
    )?;
    let nr = model.responses.len();
    let mut values = Vec::with_capacity(stored * nr);
    for k in 0..stored {
        for r in 0..nr {
            values.push(res.response_value(model, r, k));
        }
    }
    out.set_item("values", values)?;
    let n = model.mesh.n_nodes();
    let mut disp = Vec::with_capacity(stored * n * 3);
    for z in &res.states {
        for i in 0..n {
            disp.extend_from_slice(&z[node_dofs(i)]);
        }
    }
    out.set_item("displacements", disp)?;
    out.set_item("n_nodes", n)?;
    let mut nominal = vec![0.0; stored * n];
    let mut current = vec![0.0; stored * n];
    let mut state = vec![-1.0; stored * n];
    for k in 0..stored {
        let f = fricsens::output::contact_fields(model, res, k);
        for (name, _, v) in &f.point {
            let slot = match name.as_str() {
                "contact_pressure_nominal" => &mut nominal,
                "contact_pressure_current" => &mut current,
                "contact_state" => &mut state,
                _ => continue,
            };
            slot[k * n..(k + 1) * n].copy_from_slice(v);
        }
    }
    out.set_item("contact_pressure", nominal)?;
    out.set_item("contact_pressure_current", current)?;
    out.set_item("contact_state", state)?;
    out.set_item(
        "cost",
        serde_json::to_string(&res.cost).expect("serialises"),
    )?;
    Ok(out)
}

/// The built-in scenes: `(name, description)` pairs.
#[pyfunction]
fn builtin_scenes() -> Vec<(String, String)> {
    fricsens::scene::builtin_list()
        .into_iter()
        .map(|(n, d)| (n.to_string(), d.to_string()))
        .collect()
}

/// The Rust side of `fricsens`.
#[pymodule]
fn _fricsens(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(builtin_scenes, m)?)?;
    let py = m.py();
    m.add("FricsensError", py.get_type::<FricsensError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("ParameterError", py.get_type::<ParameterError>())?;
    let analysis = py.get_type::<AnalysisError>();
    // what an analysis computed before it stopped: set on the instances that have it
    analysis.setattr("partial", py.None())?;
    m.add("AnalysisError", analysis)?;
    Ok(())
}
