"""Many fits at once: one Dask task per target, each writing the usual fit outputs into its
own folder, the batch table updated as each finishes.

Rerunning the same command skips every target whose folder holds a finished fit made from
the same target, model and settings (a fingerprint of the three, ``batch_fingerprint.txt``),
and resumes unfinished ones from their checkpoints. The folders must be on a file system the
workers share with the client (always true for the default local cluster).
"""

from __future__ import annotations

import csv
import glob
import json
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import ModelError, SimulationError, check_range
from ..io.fingerprint import fingerprint
from .report import write_batch_page, write_batch_table

FINGERPRINT_FILE = "batch_fingerprint.txt"


@dataclass(frozen=True)
class FitJob:
    """One target of a batch: its file (or ``builtin:NAME``), model and column mapping."""

    name: str
    target: str
    model: str = "builtin:elbow-curl"
    column: str | None = None


def expand_targets(targets, model: str = "builtin:elbow-curl", manifest=None) -> list[FitJob]:
    """Jobs from target files and globs (each with ``model``), or from a manifest CSV with
    columns ``target,model,column`` (model and column optional; paths relative to the
    manifest). Folder names are the target file stems, made unique."""
    specs: list[tuple[str, str, str | None]] = []
    if manifest is not None:
        path = Path(manifest)
        try:
            with path.open(newline="", encoding="utf-8-sig") as fh:
                reader = csv.DictReader(fh)
                rows = list(reader)
                header = reader.fieldnames or []
        except OSError as exc:
            raise ModelError("--manifest", f"cannot read {str(path)!r}: {exc.strerror}") \
                from None
        except (UnicodeDecodeError, csv.Error):
            raise ModelError("--manifest", f"{path.name} is not a UTF-8 CSV text file; "
                             "allowed: a CSV with a header target,model,column") from None
        if "target" not in header:
            raise ModelError("--manifest", f"{path.name}: needs a header with 'target' (and "
                             "optionally 'model', 'column')")
        if not rows:
            raise ModelError("--manifest", f"{path.name}: no targets below the header; "
                             "allowed: one row per target")
        def resolve(spec: str) -> str:
            """Paths in the manifest are relative to it."""
            return (spec if spec.startswith("builtin:") or Path(spec).is_absolute()
                    else str(path.parent / spec))

        for i, row in enumerate(rows, 2):
            target = (row.get("target") or "").strip()
            if not target:
                raise ModelError("--manifest", f"{path.name} line {i}: empty target")
            own = (row.get("model") or "").strip()
            specs.append((resolve(target), resolve(own) if own else model,
                          (row.get("column") or "").strip() or None))
    if isinstance(targets, str):
        raise ModelError("targets", "expected a list of target files, globs or builtin: "
                         f"names, got the string {targets!r}; allowed: [{targets!r}]")
    for spec in targets:
        matches = [spec] if spec.startswith("builtin:") else sorted(glob.glob(spec))
        if not matches:
            raise ModelError("TARGET", f"{spec!r} matches no file")
        specs += [(m, model, None) for m in matches]
    if not specs:
        raise ModelError("TARGET", "no targets; allowed: files, globs or --manifest")
    jobs, used, seen = [], set(), set()
    for target, job_model, column in specs:
        # absolute paths: Dask workers run in folders of their own
        target, job_model = _absolute(target), _absolute(job_model)
        if (target, job_model, column) in seen:  # the same fit once
            continue
        seen.add((target, job_model, column))
        stem = target.replace(":", "-") if target.startswith("builtin:") else Path(target).stem
        name, k = stem, 2
        while name in used:
            name, k = f"{stem}_{k}", k + 1
        used.add(name)
        jobs.append(FitJob(name, target, job_model, column))
    return jobs


def _absolute(spec: str) -> str:
    return spec if spec.startswith("builtin:") else str(Path(spec).resolve())


def job_fingerprint(job: FitJob, settings: dict) -> str:
    """Hash of the target's content, the model file's content and the fit settings."""
    files = [spec if spec.startswith("builtin:") else Path(spec).read_bytes()
             for spec in (job.target, job.model)]
    return fingerprint(*files, json.dumps([job.column, settings], sort_keys=True))


def run_job(job: FitJob, settings: dict, folder: str, key: str, stop: str | None = None
            ) -> dict:
    """Fit one target into ``folder`` (a Dask task): resume from its checkpoint when it
    holds one of this fit; a bad file or a failed fit is its own row's one-line error. The
    folder's fit lock is held throughout (no two fits write one folder, wherever they run);
    the fit stops, writing the best so far and its checkpoint, when the client sets the Dask
    event ``stop`` (Ctrl-C)."""
    from ..fitting import FitProblem, ParameterSpace, SearchSettings, load_target
    from ..fitting.fit import load_checkpoint
    from ..fitting.outputs import CHECKPOINT_FILE, fit_and_write
    from ..io.model_file import load_model
    from .engine import single_threaded, stop_flag, worker_name

    single_threaded()
    row = {"name": job.name, "target": job.target, "model": job.model,
           "worker": worker_name()}
    start = time.perf_counter()
    out = Path(folder)
    try:
        model = load_model(job.model)
        target = load_target(job.target, model, job.column, settings.get("units"))
        problem = FitProblem(target, ParameterSpace.for_model(model), model,
                             settings["method"], settings["step"],
                             weight_effort=settings["weight_effort"])
        search = SearchSettings(search=settings["search"], seed=settings["seed"],
                                starts=settings["starts"], iterations=settings["iterations"])
        checkpoint = out / CHECKPOINT_FILE
        state = None
        if checkpoint.is_file():
            try:
                state = load_checkpoint(checkpoint, problem, search)
            except ModelError:
                state = None  # another fit's checkpoint: start again
        problem, outcome, summary, _files = fit_and_write(problem, search, out, resume=state,
                                                          should_stop=stop_flag(stop))
        if outcome.interrupted:
            row.update(_summary_figures(summary), status="interrupted",
                       error="stopped: best so far and checkpoint written")
        else:
            (out / FINGERPRINT_FILE).write_text(key + "\n")
            row.update(_summary_figures(summary), status="done", error="")
    except (ModelError, SimulationError, OSError) as exc:
        row.update(status="failed", error=str(exc).splitlines()[0] if str(exc) else
                   type(exc).__name__)
    row["wall_time_s"] = time.perf_counter() - start
    return row


def _summary_figures(summary: dict) -> dict:
    """The batch table's figures of one fit summary."""
    return {"rms_deg": summary["rms_error_deg"], "max_deg": summary["max_error_deg"],
            "reference_rms_deg": summary["reference_rms_error_deg"],
            "simulations": summary["simulations"], "wall_time_s": summary["wall_time_s"]}


def _finished_row(job: FitJob, folder: Path, key: str) -> dict | None:
    """The row of a fit finished earlier with the same fingerprint, else None."""
    try:
        if (folder / FINGERPRINT_FILE).read_text().strip() != key:
            return None
        summary = json.loads((folder / "fit_summary.json").read_text())
    except (OSError, ValueError):
        return None
    return {"name": job.name, "target": job.target, "model": job.model,
            "status": "done earlier", "worker": "", "error": "", **_summary_figures(summary)}


def _check_settings(jobs: list[FitJob], settings: dict) -> None:
    """Settings that would fail every fit are the command's error, not each row's: the
    search, the method, the step and every distinct model file."""
    from ..fitting import SearchSettings
    from ..io.model_file import load_model
    from ..solvers.techniques import FIT_METHODS

    SearchSettings(search=settings["search"], seed=settings["seed"],
                   starts=settings["starts"], iterations=settings["iterations"])
    if settings["method"] not in FIT_METHODS:
        raise ModelError("--method", f"{settings['method']!r}; allowed: "
                         f"{', '.join(FIT_METHODS)}")
    if settings["step"] is not None:  # None: each model's default (`default_step`)
        check_range("--step", settings["step"], 1e-5, 1.0, unit="s")
    check_range("--weight-effort", settings["weight_effort"], 0.0, 1e6)
    for spec in dict.fromkeys(job.model for job in jobs):
        load_model(spec)


def fit_many(targets=(), *, out, model: str = "builtin:elbow-curl", manifest=None,
             method: str = "imex", step: float | None = None, search: str = "least-squares",
             seed: int = 1, starts: int = 4, iterations: int = 200,
             weight_effort: float = 0.0, units: str | None = None, client=None,
             workers: int | None = None, scheduler: str | None = None, progress=None):
    """Fit every target (files, globs, ``builtin:`` names or a ``manifest`` CSV) on Dask,
    each into ``out/NAME/``; write ``out/batch.csv`` as fits finish and ``out/batch.html``
    at the end. Returns the table as a pandas DataFrame (one row per target: status, errors,
    simulations, wall time, worker, the error of a failed row)."""
    import uuid

    import pandas as pd

    from .engine import check_scheduler, check_shared_folder, connect, run_tasks

    out = Path(out).resolve()  # absolute: Dask workers run in folders of their own
    if out.exists() and not out.is_dir():
        raise ModelError("--out", f"{str(out)!r} is a file; allowed: a directory")
    jobs = expand_targets(targets, model, manifest)
    settings = {"method": method, "step": step, "search": search, "seed": seed,
                "starts": starts, "iterations": iterations, "weight_effort": weight_effort,
                "units": units}
    _check_settings(jobs, settings)
    rows: list[dict | None] = [None] * len(jobs)
    keys = []
    for i, job in enumerate(jobs):
        try:
            keys.append(job_fingerprint(job, settings))
        except OSError as exc:
            keys.append("")
            rows[i] = {"name": job.name, "target": job.target, "model": job.model,
                       "status": "failed", "error": f"cannot read: {exc.strerror}"}
            continue
        rows[i] = _finished_row(job, out / job.name, keys[i])
    todo = [i for i, r in enumerate(rows) if r is None]

    def record(k, row):
        rows[todo[k]] = row
        write_batch_table(out, [r for r in rows if r is not None])

    if scheduler is not None:
        check_scheduler(scheduler)
    stop = f"torquesim-stop-{uuid.uuid4().hex}"
    created = not out.exists()
    with connect(client, workers=workers, scheduler=scheduler,
                 in_process=len(todo) <= 1) as dask_client:
        out.mkdir(parents=True, exist_ok=True)
        try:
            check_shared_folder(dask_client, out)
        except ModelError:
            if created:
                out.rmdir()
            raise
        write_batch_table(out, [r for r in rows if r is not None])
        try:
            if todo:
                run_tasks(dask_client, [(run_job, (jobs[i], settings, str(out / jobs[i].name),
                                                   keys[i], stop)) for i in todo], record,
                          progress=progress, stop_event=stop)
        finally:
            for i in todo:
                if rows[i] is None:
                    rows[i] = {"name": jobs[i].name, "target": jobs[i].target,
                               "model": jobs[i].model, "status": "not run", "error": ""}
            write_batch_table(out, rows)
            write_batch_page(out, rows, settings)
    return pd.DataFrame(rows)
