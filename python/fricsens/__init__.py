"""fricsens from Python: frictional contact analyses and their design sensitivities.

Load a scene (built-in, a TOML file or TOML text), set design parameters, run it, and get
NumPy arrays::

    import fricsens
    scene = fricsens.Scene.load("uniaxial-j2")
    run = scene.run()                       # responses, displacements, contact pressures
    sens = scene.sensitivity(["E", "H"], method="ddm")
    sens.derivative("alpha", "H")           # d alpha / d H at every increment

Every sensitivity method of the library is there (``ddm``, ``sdm``, ``sdm-central``, ``fdm``,
``fdm-central``), with ``beta=`` and ``tangent=``; the kink flags and the cost ledger come back
as Python objects. ``fricsens.Map`` wraps a scene as a differentiable map from design
parameters to responses for ``scipy.optimize`` (value and Jacobian in one run).

Runs release the GIL; ``progress=callable(increment, time)`` is called after each converged
increment. Errors are :class:`FricsensError` and its subclasses, carrying the library's
messages; an :class:`AnalysisError` also carries ``partial``, what the analysis computed for the
increments that converged before it stopped (a :class:`Run` or a :class:`Sensitivity`, or None).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from . import _fricsens
from ._fricsens import AnalysisError, FricsensError, ParameterError, SceneError

__all__ = [
    "AnalysisError",
    "Cost",
    "FricsensError",
    "Kink",
    "Map",
    "ParameterError",
    "Run",
    "Scene",
    "SceneError",
    "Sensitivity",
    "builtin_scenes",
]

Progress = Optional[Callable[[int, float], None]]


def builtin_scenes() -> Dict[str, str]:
    """The built-in scenes, name to description."""
    return dict(_fricsens.builtin_scenes())


@dataclass(frozen=True)
class Kink:
    """A point where the converged state sits on a transition (non-differentiable)."""

    kind: str
    """``Yield`` (a Gauss point on the elastic/plastic transition), ``Friction`` (stick/slip)
    or ``Contact`` (open/closed)."""
    at: int
    """Element (Yield) or flat hitting-node number."""
    point: int
    """Gauss point (or 0)."""
    distance: float
    """Distance to the transition."""


@dataclass(frozen=True)
class Cost:
    """A method's work, as the library's cost ledger (``SensitivityCost``) has it."""

    wall_seconds: float
    residual_evaluations: int
    factorizations: int
    solve_columns: int
    primal_reruns: int
    evaluation_seconds: float
    factor_seconds: float
    solve_seconds: float
    primal_seconds: float
    """The nominal primal run's own time."""
    ledger: Dict[str, float] = field(default_factory=dict)
    """Every entry of the ledger."""


@dataclass
class Run:
    """A primal analysis. Index 0 of every array is the initial state."""

    times: np.ndarray
    """(n_increments + 1,) pseudo-times."""
    responses: List[str]
    values: np.ndarray
    """(n_increments + 1, n_responses)."""
    displacements: np.ndarray
    """(n_increments + 1, n_nodes, 3) nodal displacements."""
    contact_pressure: np.ndarray
    """(n_increments + 1, n_nodes) normal force over reference tributary area (0 off contact)."""
    contact_pressure_current: np.ndarray
    """(n_increments + 1, n_nodes) over the current tributary area."""
    contact_state: np.ndarray
    """(n_increments + 1, n_nodes): -1 not a hitting node, 0 open, 1 closed, 2 stick, 3 slip."""
    cost: Dict[str, float]

    def response(self, name: str) -> np.ndarray:
        """Response ``name`` at every increment."""
        return self.values[:, _index(self.responses, name, "response")]


@dataclass
class Sensitivity:
    """A sensitivity analysis: every response and its derivative with respect to every
    parameter, at every converged increment (no initial state)."""

    method: str
    beta: Optional[float]
    parameters: List[str]
    responses: List[str]
    increments: np.ndarray
    times: np.ndarray
    values: np.ndarray
    """(n_increments, n_responses)."""
    derivatives: np.ndarray
    """(n_increments, n_responses, n_parameters)."""
    error_bars: Optional[np.ndarray]
    """``beta="auto"``: (n_increments, n_responses, n_parameters), else None."""
    betas: Optional[np.ndarray]
    """``beta="auto"``: the relative step chosen, (n_increments, n_parameters)."""
    kinks: List[List[Kink]]
    """Per increment, the flagged non-differentiable points."""
    one_sided: List[Optional[dict]]
    """Per increment (DDM at flagged increments): ``{"lower": [[..]], "upper": [[..]]}``, a
    side ``None`` where its solve failed, with ``"failed"``: why, one line a failed side."""
    cost: Cost
    displacement_derivatives: Optional[np.ndarray] = None
    """``fields=True``: (n_increments, n_parameters, n_nodes, 3)."""

    def value(self, response: str) -> np.ndarray:
        """Response ``response`` at every increment."""
        return self.values[:, _index(self.responses, response, "response")]

    def derivative(self, response: str, parameter: str) -> np.ndarray:
        """d response / d parameter at every increment."""
        r = _index(self.responses, response, "response")
        p = _index(self.parameters, parameter, "parameter")
        return self.derivatives[:, r, p]


def _index(names: Sequence[str], name: str, what: str) -> int:
    try:
        return list(names).index(name)
    except ValueError:
        raise FricsensError(f"no {what} `{name}` (there are: {', '.join(names)})") from None


class Scene:
    """A scene with design-parameter values set on it. Immutable: ``with_values`` returns a
    new one."""

    def __init__(self, inner: _fricsens.Scene):
        self._inner = inner

    @staticmethod
    def load(name_or_path: str) -> "Scene":
        """A built-in scene by name (``builtin_scenes()``) or a TOML file."""
        return Scene(_fricsens.Scene.load(str(name_or_path)))

    @staticmethod
    def from_toml(text: str, source: str = "<string>") -> "Scene":
        """A scene from TOML text; ``source`` names it in error messages."""
        return Scene(_fricsens.Scene.from_toml(text, source))

    @property
    def name(self) -> str:
        return self._inner.name

    @property
    def responses(self) -> List[str]:
        """The response names, in the order of the result columns."""
        return list(self._inner.responses)

    @property
    def times(self) -> np.ndarray:
        """The pseudo-times that end the scene's increments (cut-back sub-increments the
        solver adds fall between them)."""
        return np.asarray(self._inner.times, dtype=float)

    @property
    def study_parameters(self) -> List[str]:
        """The parameters the scene's ``[study]`` declares."""
        return list(self._inner.study_parameters)

    @property
    def study_beta(self) -> float:
        return self._inner.study_beta

    def get(self, name: str) -> float:
        """The value of design parameter ``name`` (``mu``, ``E``, ``upper.length.x``, ...)."""
        return self._inner.get(name)

    def with_values(self, **values: float) -> "Scene":
        """A copy with design parameters set, e.g. ``scene.with_values(mu=0.3)``; a name
        with dots is given as ``scene.with_values(**{"upper.length.x": 90.0})``."""
        inner = self._inner
        for k, v in values.items():
            inner = inner.with_value(k, float(v))
        return Scene(inner)

    def to_toml(self) -> str:
        return self._inner.to_toml()

    def run(self, progress: Progress = None) -> Run:
        """The primal analysis. If it stops, the :class:`AnalysisError` raised carries the
        increments that converged as ``partial``, a :class:`Run` (None if none did)."""
        try:
            d = self._inner.run(progress)
        except AnalysisError as e:
            _with_partial(e, _run_from)
            raise
        return _run_from(d)

    def sensitivity(
        self,
        params: Union[str, Sequence[str], None] = None,
        method: str = "ddm",
        beta: Union[float, str, None] = None,
        tangent: str = "exact",
        fields: bool = False,
        rigid_modes: bool = False,
        progress: Progress = None,
    ) -> Sensitivity:
        """Every response's derivative with respect to ``params`` (default: the study's)
        by ``method``: ``ddm``, ``sdm``, ``sdm-central``, ``fdm``, ``fdm-central`` or ``adjoint`` (every increment).
        ``beta``: the relative perturbation (None: the study's; ``"auto"`` for SDM and FDM);
        ``tangent``: ``exact``, ``last`` or ``refined``; ``fields``: also the derivative of
        the displacement field; ``rigid_modes``: the refined SDM for shape parameters (``sdm``,
        ``sdm-central``; each element's rigid rotation differentiated exactly). If the analysis stops, the :class:`AnalysisError` raised
        carries, for the in-line methods (``ddm``, ``sdm``, ``sdm-central``), the increments
        that converged as ``partial``, a :class:`Sensitivity` (None for the finite
        differences and the adjoint, which need the whole history)."""
        if params is None:
            params = self.study_parameters
        elif isinstance(params, str):
            params = [params]
        try:
            d = self._inner.sensitivity(
                list(params), method, beta, tangent, fields, rigid_modes, progress
            )
        except AnalysisError as e:
            _with_partial(e, lambda p: _sensitivity_from(p, fields))
            raise
        return _sensitivity_from(d, fields)


def _with_partial(e: AnalysisError, convert: Callable[[dict], object]) -> None:
    """Replace the extension's raw ``partial`` (a dict, or None) by the package's object."""
    raw = getattr(e, "partial", None)
    e.partial = None if raw is None else convert(raw)


def _run_from(d: dict) -> Run:
    """A :class:`Run` from the extension's dict."""
    n = d["n_nodes"]
    times = np.asarray(d["times"], dtype=float)
    k = len(times)
    return Run(
        times=times,
        responses=list(d["responses"]),
        values=np.asarray(d["values"], dtype=float).reshape(k, len(d["responses"])),
        displacements=np.asarray(d["displacements"], dtype=float).reshape(k, n, 3),
        contact_pressure=np.asarray(d["contact_pressure"], dtype=float).reshape(k, n),
        contact_pressure_current=np.asarray(
            d["contact_pressure_current"], dtype=float
        ).reshape(k, n),
        contact_state=np.asarray(d["contact_state"], dtype=float).reshape(k, n).astype(int),
        cost=json.loads(d["cost"]),
    )


def _sensitivity_from(d: dict, fields: bool) -> Sensitivity:
    """A :class:`Sensitivity` from the extension's dict."""
    ni, nr, npar = len(d["times"]), len(d["responses"]), len(d["parameters"])
    ledger = json.loads(d["cost"])
    bars = np.asarray(d["error_bars"], dtype=float)
    betas = np.asarray(d["betas"], dtype=float)
    kinks = [[Kink(kind=k["kind"], at=k["at"], point=k["point"], distance=k["distance"])
              for k in inc] for inc in json.loads(d["kinks"])]
    out = Sensitivity(
        method=d["method"],
        beta=d["beta"],
        parameters=list(d["parameters"]),
        responses=list(d["responses"]),
        increments=np.asarray(d["increments"], dtype=int),
        times=np.asarray(d["times"], dtype=float),
        values=np.asarray(d["values"], dtype=float).reshape(ni, nr),
        derivatives=np.asarray(d["derivatives"], dtype=float).reshape(ni, nr, npar),
        error_bars=bars.reshape(ni, nr, npar) if bars.size else None,
        betas=betas.reshape(ni, npar) if betas.size else None,
        kinks=kinks,
        one_sided=json.loads(d["one_sided"]),
        cost=Cost(
            wall_seconds=ledger["wall_seconds"],
            residual_evaluations=ledger["residual_evaluations"],
            factorizations=ledger["factorizations"],
            solve_columns=ledger["solve_columns"],
            primal_reruns=ledger["primal_reruns"],
            evaluation_seconds=ledger["evaluation_seconds"],
            factor_seconds=ledger["factor_seconds"],
            solve_seconds=ledger["solve_seconds"],
            primal_seconds=d["primal_seconds"],
            ledger=ledger,
        ),
    )
    if fields:
        n = d["n_nodes"]
        out.displacement_derivatives = np.asarray(
            d["displacement_derivatives"], dtype=float
        ).reshape(ni, npar, n, 3)
    return out


class Map:
    """A scene as a differentiable map from design parameters to responses, for
    ``scipy.optimize``: ``x`` holds the values of ``params``, the output the ``responses`` at
    the pseudo-times ``times`` (default: the ends of the scene's increments, so that a design
    whose analysis cuts back keeps the same rows), flattened time-major. One analysis gives
    the value and its Jacobian (``method``, default DDM; ``"fdm"``/``"fdm-central"`` reruns
    the analysis per parameter); ``method=None`` runs the primal analysis alone and gives no
    Jacobian (for an optimiser's own finite differences).

    ``Map.fun`` and ``Map.jac`` share one analysis per ``x`` (cached), as
    ``scipy.optimize.least_squares(m.fun, x0, jac=m.jac)`` calls them;
    ``Map.value_and_jacobian`` gives both at once."""

    def __init__(
        self,
        scene: Scene,
        params: Sequence[str],
        responses: Sequence[str],
        times: Optional[Sequence[float]] = None,
        method: Optional[str] = "ddm",
        beta: Union[float, str, None] = None,
    ):
        self.scene = scene
        self.params = list(params)
        self.responses = list(responses)
        self.times = scene.times if times is None else np.asarray(times, dtype=float)
        self.method = method
        self.beta = beta
        self.analyses = 0
        """Analyses run so far (one per distinct ``x``)."""
        self._cache = None

    def _rows(self, times: np.ndarray) -> np.ndarray:
        rows = []
        for t in self.times:
            hit = np.flatnonzero(np.abs(times - t) <= 1e-12 * max(abs(t), 1.0))
            if hit.size == 0:
                raise FricsensError(f"{self.scene.name}: the analysis has no increment at t = {t}")
            rows.append(hit[0])
        return np.asarray(rows)

    def value_and_jacobian(self, x: Sequence[float]):
        """The responses (m,) and their Jacobian (m, len(params)) at ``x`` (None without a
        method)."""
        x = np.asarray(x, dtype=float)
        if self._cache is not None and np.array_equal(self._cache[0], x):
            return self._cache[1], self._cache[2]
        scene = self.scene.with_values(**dict(zip(self.params, x.tolist())))
        self.analyses += 1
        if self.method is None:
            run = scene.run()
            rows = self._rows(run.times)
            cols = [_index(run.responses, r, "response") for r in self.responses]
            value = run.values[rows][:, cols].reshape(-1)
            jac = None
        else:
            s = scene.sensitivity(self.params, method=self.method, beta=self.beta)
            rows = self._rows(s.times)
            cols = [_index(s.responses, r, "response") for r in self.responses]
            value = s.values[rows][:, cols].reshape(-1)
            jac = s.derivatives[rows][:, cols, :].reshape(-1, len(self.params))
        self._cache = (x.copy(), value, jac)
        return value, jac

    def fun(self, x):
        """The responses at ``x``."""
        return self.value_and_jacobian(x)[0]

    def jac(self, x):
        """Their Jacobian at ``x``."""
        return self.value_and_jacobian(x)[1]
