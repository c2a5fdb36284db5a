"""Monte Carlo and grid sweeps over model parameters, simulated in chunks on Dask workers.

A parameter is named by its path in the model (`torquesim.model.paths`, the vocabulary of
``compare --vary`` and ``fit --bound``): ``UNIT.FIELD``, ``UNIT.rampN.FIELD``,
``JOINT.FIELD``, ``SEGMENT.FIELD``, ``SEGMENT.LOAD.FIELD``, ``gravity``, ``base_angle`` or
``landing_speed``.
Distributions: ``uniform(LOW,HIGH)``, ``normal(MEAN,SD)``, ``lognormal(MEDIAN,SIGMA)`` (σ of
the logarithm) or ``grid(LOW,HIGH,N)``. Samples are drawn in the client from the seed (or
a scrambled Sobol' sequence), so the table does not depend on the number of workers.
"""

from __future__ import annotations

import json
import math
import os
import re
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelError, SimulationError, check_range
from ..fitting.problem import DEFAULT_METHOD
from ..io.fingerprint import fingerprint as hash_parts
from ..model.chain import ChainModel, as_chain
from ..model.paths import parse_assignment, set_parameter
from ..solvers.choice import choose_technique
from ..solvers.simulation import DEFAULT_TOLERANCE
from ..solvers.techniques import FIT_METHODS

DISTRIBUTIONS = ("uniform", "normal", "lognormal", "grid")
#: Points of each joint's angle history kept per sample (for the percentile bands).
HISTORY_POINTS = 101
DEFAULT_CHUNK = 1000


@dataclass(frozen=True)
class Distribution:
    """A named parameter's distribution: kind and its two (grid: three) numbers."""

    path: str
    kind: str
    a: float
    b: float
    n: int = 0

    def sample(self, uniforms: np.ndarray) -> np.ndarray:
        """Values at the quantiles ``uniforms`` (0–1)."""
        from scipy.special import ndtri  # the normal quantile (scipy.stats.norm.ppf's)

        if self.kind == "uniform":
            return self.a + (self.b - self.a) * uniforms
        if self.kind == "normal":
            return ndtri(uniforms) * self.b + self.a
        return self.a * np.exp(self.b * ndtri(uniforms))  # lognormal

    def grid(self) -> np.ndarray:
        return np.linspace(self.a, self.b, self.n)


def parse_vary(text: str) -> Distribution:
    """``PATH=KIND(a,b[,n])`` → `Distribution` (PATH: `torquesim.model.paths`)."""
    example = "flexor.se_stiffness=normal(600,60)"
    path, spec = parse_assignment(text, "--vary", example)
    found = re.fullmatch(r"\s*(\w+)\s*\(([^)]*)\)\s*", spec)
    if not found or found.group(1) not in DISTRIBUTIONS:
        raise ModelError("--vary", f"{text!r}; allowed PATH=KIND(...), KIND one of "
                         f"{', '.join(DISTRIBUTIONS)}, e.g. {example}")
    kind = found.group(1)
    try:
        numbers = [float(v) for v in found.group(2).split(",")]
    except ValueError:
        numbers = []
    count = 3 if kind == "grid" else 2
    if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
        raise ModelError("--vary", f"{text!r}: {kind} takes {count} finite numbers")
    a, b = numbers[:2]
    if kind == "uniform" and not a < b:
        raise ModelError("--vary", f"{text!r}: uniform(LOW,HIGH) needs LOW < HIGH")
    if kind in ("normal", "lognormal") and not b > 0:
        raise ModelError("--vary", f"{text!r}: the spread must be > 0")
    if kind == "lognormal" and not a > 0:
        raise ModelError("--vary", f"{text!r}: lognormal(MEDIAN,SIGMA) needs MEDIAN > 0")
    if kind == "grid":
        n = numbers[2]
        if not (n == int(n) and 1 <= n <= 10_000 and a <= b):
            raise ModelError("--vary", f"{text!r}: grid(LOW,HIGH,N) needs LOW ≤ HIGH and N "
                             "a whole number in [1, 10000]")
        return Distribution(path.strip(), kind, a, b, int(n))
    return Distribution(path.strip(), kind, a, b)


def sample_matrix(distributions, samples: int, seed: int, sobol: bool = False) -> np.ndarray:
    """(N, P) parameter values: Monte Carlo (or Sobol') over the non-grid distributions,
    crossed with every grid; with only grids, their Cartesian product (``samples`` unused)."""
    random = [d for d in distributions if d.kind != "grid"]
    grids = [d for d in distributions if d.kind == "grid"]
    rows = 1
    draws = np.empty((1, 0))
    if random:
        if sobol:
            from scipy.stats import qmc

            uniforms = qmc.Sobol(d=len(random), scramble=True, seed=seed).random(samples)
        else:
            uniforms = np.random.default_rng(seed).random((samples, len(random)))
        uniforms = np.clip(uniforms, 1e-12, 1 - 1e-12)
        draws = np.column_stack([d.sample(uniforms[:, i]) for i, d in enumerate(random)])
        rows = samples
    mesh = np.array(np.meshgrid(*[g.grid() for g in grids], indexing="ij")).reshape(
        len(grids), -1).T if grids else np.empty((1, 0))
    combined = np.empty((rows * mesh.shape[0], len(distributions)))
    order = [distributions.index(d) for d in random] + [distributions.index(d) for d in grids]
    block = np.hstack([np.repeat(draws, mesh.shape[0], axis=0), np.tile(mesh, (rows, 1))])
    combined[:, order] = block
    return combined


def outcome_columns(model: ChainModel) -> list[str]:
    """The outcome columns of a sweep's table for ``model``."""
    out = []
    for joint in model.joints:
        out += [f"peak_{joint.name}_deg", f"peak_{joint.name}_time_s",
                f"final_{joint.name}_deg"]
    return out + ["max_unit_torque_nm", "estimated_error_deg", "step_s", "accuracy", "error"]


#: A sweep row's ``accuracy``: ``ok``; ``unstable`` (beyond the RK4 stability limit);
#: ``inaccurate`` (estimated max angle error above the tolerance, or a step too coarse for the
#: activation); ``failed`` (no result; the error says why). ``unstable`` and ``inaccurate``
#: are what is left after `MAX_REFINEMENTS` halvings of the step.
ACCURACY_VERDICTS = ("ok", "unstable", "inaccurate", "failed")
#: A sample found inaccurate or unstable is simulated again at half the step (as `simulate`'s
#: advice), at most this many times (the sweep's step / 32): its row gives the step that met
#: the tolerance.
MAX_REFINEMENTS = 5


def simulate_chunk(base: ChainModel, paths: list[str], values: np.ndarray, method: str,
                   step: float, tolerance: float = DEFAULT_TOLERANCE) -> dict:
    """Simulate every row of ``values`` (a Dask task). Returns the outcome arrays, the angle
    histories (samples × joints × `HISTORY_POINTS`, deg, NaN for failed samples), each
    row's accuracy verdict (`ACCURACY_VERDICTS`; every run's max angle error is estimated
    against a run at twice the step, `simulate`'s default check, within ``tolerance`` rad; a
    sample found inaccurate or unstable is run again at half the step, up to
    `MAX_REFINEMENTS` times, and its row gives the step it was run at) and the worker. A
    sample whose run fails is run again at half the step too (a step too coarse for its
    parameters); one that still fails fills its own row with its one-line error."""
    from ..solvers.simulation import simulate
    from .engine import single_threaded, worker_name

    single_threaded()
    n = base.n_joints
    m = values.shape[0]
    numbers = np.full((m, 3 * n + 3), np.nan)
    accuracy = ["failed"] * m
    errors = [""] * m
    grid = np.linspace(0.0, base.duration, HISTORY_POINTS)
    histories = np.full((m, n, HISTORY_POINTS), np.nan, dtype=np.float32)
    for i, row in enumerate(values):
        try:
            model = base
            for path, value in zip(paths, row, strict=True):
                model = set_parameter(model, path, value)
            h = step
            for refinement in range(MAX_REFINEMENTS + 1):
                result = simulate(model, method, h, check=False, advise=False,
                                  tolerance=tolerance)
                if not result.success:
                    if refinement == MAX_REFINEMENTS:
                        raise SimulationError(result.message)
                    h /= 2
                    continue
                verdict = ("unstable" if result.stability is not None
                           and result.stability.exceeded else
                           "inaccurate" if result.message else "ok")
                if verdict == "ok":
                    break
                h /= 2
        except (ModelError, SimulationError) as exc:
            errors[i] = str(exc).splitlines()[0]
            continue
        q = np.degrees(result.q)
        for j in range(n):
            peak = int(np.argmax(q[:, j]))
            numbers[i, 3 * j: 3 * j + 3] = q[peak, j], result.time[peak], q[-1, j]
            histories[i, j] = np.interp(grid, result.time, q[:, j])
        numbers[i, -3] = max_unit_torque(model, result.states)
        numbers[i, -2] = math.degrees(result.settings.get("estimated_error_rad", math.nan))
        numbers[i, -1] = result.step
        accuracy[i] = verdict
        errors[i] = result.message
    return {"numbers": numbers, "accuracy": accuracy, "errors": errors, "histories": histories,
            "worker": worker_name()}


def max_unit_torque(model: ChainModel, states: np.ndarray) -> float:
    """The largest SE torque k·max(d·(θ_cc − ψ), 0) of any unit over the run, N·m, ψ the
    unit's angle (docs/model.md §2; the same as the ``torque_<unit>`` output columns)."""
    psi = model.unit_angles(states[:, model.layout.angles])
    worst = 0.0
    for u, unit in enumerate(model.units):
        stretch = unit.direction * (states[:, model.layout.unit_state(u)] - psi[:, u])
        worst = max(worst, unit.parameters.se_stiffness * float(np.max(stretch)))
    return worst


def fingerprint(model_toml: str, values: np.ndarray, method: str, step: float, paths,
                tolerance: float = DEFAULT_TOLERANCE) -> str:
    """Hash of what a finished chunk is valid for."""
    return hash_parts(model_toml, np.asarray(values, dtype=float),
                      (method, step, list(paths), tolerance, "refined-step"))


#: Work (samples × steps × units) below which a sweep runs in this process instead of starting
#: a local cluster (about 2 s of simulation on one core, less than a cluster's start-up).
SMALL_WORK = 2_000_000
#: Without an explicit chunk size, samples are split so that every worker gets at least this
#: many tasks (the load then evens out), at most `DEFAULT_CHUNK` samples each.
TASKS_PER_WORKER = 4
SWEEP_FINGERPRINT_FILE = "sweep_fingerprint.txt"


#: The sweep's default step on a fixed base, s (IMEX: the default curl within 0.5°).
FIXED_BASE_STEP = 5e-3


#: A sweep's default technique and step meet this share of its tolerance on the model as
#: given (`choose_technique`); the rest is left for the samples' variation, each sample's
#: own estimate deciding (`simulate_chunk`).
CHOICE_SHARE = 0.5


def sweep_step(model) -> float:
    """The step of a sweep of ``model`` when no step of its technique meets the tolerance
    (`choose_technique`), s: `FIXED_BASE_STEP` on a fixed base (or the largest step below it
    that divides the duration); on a body on the ground the fit's default (`default_step`:
    within its contacts' RK4 stability limit), which divides the duration. Before, every
    sweep of a jump ran at 5 ms and every sample diverged."""
    from ..fitting.problem import default_step, fit_step

    wanted = default_step(model) if model.base == "free" and model.contacts else \
        FIXED_BASE_STEP
    return fit_step(model.duration, min(wanted, model.duration))[0]


def sweep(model, vary, *, samples: int = 1000, seed: int = 1, sobol: bool = False,
          method: str | None = None, step: float | None = None, out=None,
          chunk: int | None = None,
          client=None, workers: int | None = None, scheduler: str | None = None,
          progress=None, tolerance: float = DEFAULT_TOLERANCE, overwrite: bool = False):
    """Simulate ``model`` (a chain, a file or ``builtin:NAME``) over the parameter
    distributions ``vary`` (``PATH=KIND(...)`` strings or `Distribution`) on Dask.

    ``method`` and ``step`` (s) default to the cheapest technique and step whose run of the
    model as given is within `CHOICE_SHARE` of ``tolerance`` (`choose_technique`; ``imex``
    with a given step; `sweep_step` where no step meets it); the table's
    ``attrs["choice"]`` says which. Returns (table, histories): a pandas
    DataFrame (its ``attrs["step_s"]`` the step every sample starts at) with one row per
    sample (its parameter
    values, each joint's peak angle and its time, final angle, the largest unit torque, the
    estimated max angle error and the accuracy verdict, `ACCURACY_VERDICTS`, with
    ``tolerance`` rad, default 0.5°, and any error or warning) and the angle histories
    (samples × joints × `HISTORY_POINTS`, deg). With ``out``, finished chunks are kept in
    ``out/chunks/`` as they arrive (a rerun with the same settings skips them) and the
    table, percentile figure and rank correlations are written there; a folder holding
    another sweep is refused unless ``overwrite``.

    Engine: ``client``, or a ``scheduler`` address, or a local cluster of ``workers``
    processes; small work (`SMALL_WORK`) runs in this process unless ``workers`` is
    given. ``chunk`` (samples per task) defaults to an even split giving every worker at least
    `TASKS_PER_WORKER` tasks.
    """
    from ..io.model_file import load_model, model_to_toml
    from ..solvers.simulation import step_count
    from .engine import check_scheduler, connect, workers_of

    if method is not None and method not in FIT_METHODS:
        raise ModelError("--method", f"{method!r}; allowed: {', '.join(FIT_METHODS)}")
    _whole_number("--samples", samples, 1, 10_000_000)
    if chunk is not None:
        _whole_number("--chunk", chunk, 1, 1_000_000)
    check_range("tolerance", tolerance, 0.0, math.pi, low_open=True, unit="rad")
    if isinstance(vary, str | Distribution):
        vary = [vary]
    # the distributions first: they need no model, whose checks may compile
    distributions = [d if isinstance(d, Distribution) else parse_vary(d) for d in vary]
    if not distributions:
        raise ModelError("--vary", "nothing to vary; allowed: one or more PATH=KIND(...)")
    chain = as_chain(load_model(model) if isinstance(model, str | Path) else model)
    choice = None
    if step is None:
        choice = choose_technique(chain, CHOICE_SHARE * tolerance,
                                  None if method is None else (method,))
        method, step = (choice.method, choice.step) if choice is not None else \
            (method, sweep_step(chain))
    method = method or DEFAULT_METHOD
    n_steps = step_count(chain.duration, step, "--step")
    paths = [d.path for d in distributions]
    for d in distributions:  # every path and a typical value checked before any work
        _check_ends(chain, d)
        typical = d.a if d.kind != "uniform" else 0.5 * (d.a + d.b)
        set_parameter(chain, d.path, typical, "--vary")
    values = sample_matrix(distributions, samples, seed, sobol)
    model_toml = model_to_toml(chain)
    whole = fingerprint(model_toml, values, method, step, paths, tolerance)
    out = None if out is None else Path(out).resolve()
    if out is not None:
        if out.exists() and not out.is_dir():
            raise ModelError("--out", f"{str(out)!r} is a file; allowed: a directory")
        _check_folder(out, whole, overwrite)
    small = values.shape[0] * n_steps * chain.n_units <= SMALL_WORK
    if scheduler is not None:
        check_scheduler(scheduler)

    def engine():
        return connect(client, workers=workers, scheduler=scheduler, in_process=small)

    def claim_folder():  # once connected (or with nothing to run): the folder is this sweep's
        if out is not None:
            if overwrite:
                import shutil

                shutil.rmtree(out / "chunks", ignore_errors=True)
            out.mkdir(parents=True, exist_ok=True)
            (out / SWEEP_FINGERPRINT_FILE).write_text(whole + "\n")

    if chunk is None and scheduler is None:
        n = (workers_of(client) if client is not None else
             1 if small and workers is None else workers or os.cpu_count() or 1)
        chunk = _auto_chunk(values.shape[0], n)
    if chunk is not None:
        results = _run_chunks(engine, claim_folder, chain, paths, values, method, step,
                              tolerance, chunk, model_toml, out, progress, overwrite)
    else:
        with engine() as dask_client:
            chunk = _auto_chunk(values.shape[0], workers_of(dask_client))
            results = _run_chunks(lambda: nullcontext(dask_client), claim_folder, chain,
                                  paths, values, method, step, tolerance, chunk, model_toml,
                                  out, progress, overwrite)
    starts = list(range(0, values.shape[0], chunk))
    table, histories = _assemble(chain, paths, values, [results[k] for k in range(len(starts))])
    table.attrs["step_s"] = step  # the samples' first step (a refined one has a smaller)
    table.attrs["method"] = method
    table.attrs["choice"] = None if choice is None else choice.describe()
    if out is not None:
        from .report import write_sweep

        write_sweep(out, chain, table, histories, distributions,
                    {"samples": int(values.shape[0]), "seed": seed, "sobol": sobol,
                     "method": method, "step_s": step, "chunk": chunk,
                     "tolerance_deg": math.degrees(tolerance)}, outcome_columns(chain))
    return table, histories


def _check_ends(chain: ChainModel, d: Distribution) -> None:
    """Refuse a uniform or grid distribution that reaches beyond its field's range (its
    samples there would all fail): its ends are set on the model (a uniform's a hair inside,
    as its samples are, so that an open end such as a stiffness's 0 is allowed). Ends the
    model refuses for another reason (a start the units cannot hold) are left to the
    samples, which record it."""
    if d.kind not in ("uniform", "grid"):
        return  # unbounded: a sample in a tail is recorded as failed
    inset = 1e-9 * (d.b - d.a) if d.kind == "uniform" else 0.0
    for end in (d.a + inset, d.b - inset):
        try:
            set_parameter(chain, d.path, end, "--vary")
        except ModelError as exc:
            if "out of range; allowed " in exc.reason:
                spec = f"{d.a:g},{d.b:g}" + (f",{d.n}" if d.kind == "grid" else "")
                allowed = exc.reason.split("out of range; allowed ", 1)[1]
                raise ModelError("--vary", f"{d.path}={d.kind}({spec}) reaches {end:.6g}; "
                                 f"allowed {allowed}") from None


def _whole_number(field: str, value, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) \
            or not low <= value <= high:
        raise ModelError(field, f"{value!r}; allowed a whole number from {low} to {high}")
    return int(value)


def _check_folder(out: Path, whole: str, overwrite: bool) -> None:
    """Refuse a folder that holds another sweep (unless ``overwrite``)."""
    try:
        held = (out / SWEEP_FINGERPRINT_FILE).read_text().strip()
    except OSError:
        held = "unknown" if (out / "sweep.csv").exists() else None
    if held is not None and held != whole and not overwrite:
        raise ModelError("--out", f"{str(out)!r} holds another sweep; allowed: another "
                         "folder, or --overwrite to replace it")


def _auto_chunk(samples: int, workers: int) -> int:
    """Samples per task giving every worker `TASKS_PER_WORKER` tasks or more."""
    return max(1, min(DEFAULT_CHUNK, math.ceil(samples / (TASKS_PER_WORKER * workers))))


def _run_chunks(engine, claim_folder, chain, paths, values, method, step, tolerance, chunk,
                model_toml, out, progress, overwrite) -> dict[int, dict]:
    """Simulate every chunk not finished earlier (the client writes each into
    ``out/chunks/`` as it arrives); return chunk index → result. ``engine()`` connects (only
    when there is work); ``claim_folder()`` marks the folder once it is."""
    from .engine import run_tasks

    starts = list(range(0, values.shape[0], chunk))
    results: dict[int, dict] = {}
    chunk_dir = out / "chunks" if out is not None else None
    if chunk_dir is not None and not overwrite:
        for k, s in enumerate(starts):
            kept = _load_chunk(chunk_dir / f"chunk_{k:05d}.npz",
                               fingerprint(model_toml, values[s:s + chunk], method, step, paths,
                                           tolerance))
            if kept is not None:
                results[k] = kept
    todo = [k for k in range(len(starts)) if k not in results]

    def keep(i, result):
        k = todo[i]
        results[k] = result
        if chunk_dir is not None:
            _save_chunk(chunk_dir / f"chunk_{k:05d}.npz", result,
                        fingerprint(model_toml, values[starts[k]:starts[k] + chunk], method,
                                    step, paths, tolerance))

    if not todo:
        claim_folder()
        return results
    with engine() as dask_client:
        claim_folder()
        if chunk_dir is not None:
            chunk_dir.mkdir(parents=True, exist_ok=True)
        run_tasks(dask_client, [(simulate_chunk, (chain, paths,
                                                  values[starts[k]:starts[k] + chunk],
                                                  method, step, tolerance)) for k in todo],
                  keep, progress=progress)
    return results


def _assemble(chain, paths, values, parts):
    import pandas as pd

    numbers = np.vstack([p["numbers"] for p in parts])
    table = pd.DataFrame(values, columns=paths)
    columns = outcome_columns(chain)
    for i, name in enumerate(columns[:-2]):
        table[name] = numbers[:, i]
    table["accuracy"] = [g for p in parts for g in p["accuracy"]]
    table["error"] = [e for p in parts for e in p["errors"]]
    table["worker"] = [p["worker"] for p in parts for _ in p["accuracy"]]
    table.insert(0, "sample", np.arange(len(table)))
    histories = np.concatenate([p["histories"] for p in parts])
    return table, histories


def _save_chunk(path: Path, result: dict, key: str) -> None:
    from ..io.atomic import write_atomic

    def write(tmp: Path) -> None:
        with tmp.open("wb") as fh:
            np.savez(fh, numbers=result["numbers"], histories=result["histories"],
                     meta=json.dumps({"fingerprint": key, "accuracy": result["accuracy"],
                                      "errors": result["errors"], "worker": result["worker"]}))

    write_atomic(path, write)


def _load_chunk(path: Path, key: str) -> dict | None:
    """A finished chunk made with the same settings, or None (missing, other, damaged)."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("fingerprint") != key:
                return None
            return {"numbers": data["numbers"], "histories": data["histories"],
                    "accuracy": meta["accuracy"], "errors": meta["errors"],
                    "worker": meta["worker"]}
    except Exception:  # noqa: BLE001 - a damaged chunk is simply simulated again
        return None
