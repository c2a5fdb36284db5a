"""What a run compiles: the elbow compiles none of the chains' or the ground's code, and every
model function once (one signature), so that a first run on an empty Numba cache is not
spent compiling code it never takes (the tutorial's first-run table). Checked in a fresh
interpreter on an empty cache, where a function's signatures are exactly those compiled."""

import inspect
import json
import os
import subprocess
import sys
import tempfile
import textwrap

import pytest

from torquesim.solvers import monolithic

# Both tests read one fresh-interpreter compile (20 s), made once: the tests of a file run in
# one test process (pyproject's ``--dist loadfile``).

SCRIPT = textwrap.dedent("""
    import json
    import torquesim as ts
    from torquesim.model import activation, body, torque_generator
    from torquesim.solvers import fixed_step, monolithic, partitioned, rates, result

    curl = ts.load_model("builtin:elbow-curl").replace(duration=0.3)
    ts.simulate(curl, "monolithic", 1e-4).columns()
    ts.simulate(curl, "reference", output_step=0.01).columns()

    def signatures(module):
        return {name: [[str(t) for t in s] for s in getattr(module, name).signatures]
                for name in dir(module)
                if hasattr(getattr(module, name), "signatures")
                and getattr(module, name).__module__ == module.__name__}

    print(json.dumps({m.__name__.rsplit(".", 1)[-1]: signatures(m) for m in
                      (activation, body, torque_generator, fixed_step, monolithic,
                       partitioned, rates, result)}))

    # Arrays Numba's runtime holds after more runs of the code compiled without reference
    # counting (the monolithic loop, the right-hand side), the partitioned loops beside it
    import gc

    import numpy as np
    from numba.core.runtime import rtsys

    def held():
        gc.collect()
        stats = rtsys.get_allocation_stats()
        return stats.alloc - stats.free

    jump = ts.load_model("builtin:squat-jump").replace(duration=0.02)
    runs = [(curl, "monolithic", 1e-4), (curl, "reference", 0.0), (curl, "imex", 1e-3),
            (jump, "monolithic", 2.5e-5), (jump, "imex", 2.5e-4), (jump, "reference", 0.0)]
    # the loops' arrays allocated by compiled code, as in the population kernels (an array
    # allocated from Python is not counted in the runtime's statistics)
    import numba
    from torquesim.solvers import step_loop

    @numba.njit
    def from_compiled_code(kinds, system, y0, h, n_steps, coupling, rows, width):
        out, stats = np.empty((rows, width)), np.zeros(fixed_step.STATS_SIZE)
        step_loop.run_step_loop(kinds, system, y0, h, n_steps, coupling, out, stats)
        return stats[fixed_step.STEPS]

    def run_all():
        for model, method, step in runs:
            options = {"step": step} if step else {"output_step": 1e-3}
            ts.simulate(model, method, check=False, **options).columns()
        for model in (curl, jump):
            coupling = np.zeros(fixed_step.COUPLING_SIZE)
            y0 = model.initial_state().state
            from_compiled_code(step_loop.model_step_kinds(model, True, coupling),
                               tuple(model.pack()), y0, 1e-4, 10, coupling, 11, y0.size)

    run_all()
    before = held()
    for _ in range(3):
        run_all()
    print(json.dumps({"held_before": before, "held_after": held()}))
""")


@pytest.fixture(scope="module")
def compiled():
    """{module: {function: [signature as a list of type names]}} after an elbow simulate
    (monolithic, and the reference, each with its table) on an empty Numba cache (a function
    loaded from the cache inside its caller's code would not show its signature)."""
    with tempfile.TemporaryDirectory() as cache:
        done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                              check=True, env={**os.environ, "NUMBA_CACHE_DIR": cache,
                                               "NUMBA_NRT_STATS": "1"})
    lines = done.stdout.strip().splitlines()
    return {**json.loads(lines[-2]), "runtime": json.loads(lines[-1])}


def test_the_elbow_compiles_no_chain_or_ground_code(compiled):
    """The general body solve (fixed or free base, chain or tree) and the ground's
    outputs are for bodies of two or more coordinates: an elbow run must not compile them
    (a cold elbow `simulate` and `fit` did, through branches decided at run time: 2x their
    first-run time)."""
    body = compiled["body"]
    for name in ("body_accelerations", "_free_base_terms", "ground_outputs",
                 "contact_time_constant"):
        assert body.get(name, []) == [], name
    switch = list(inspect.signature(monolithic.rk4_monolithic.py_func).parameters) \
        .index("body")
    assert compiled["monolithic"]["rk4_monolithic"]
    for signature in compiled["monolithic"]["rk4_monolithic"]:
        assert signature[switch] in ("none", "omitted(default=None)"), signature


def test_code_without_reference_counting_leaves_no_array_behind(compiled):
    """The monolithic loop and the right-hand side are compiled without Numba's reference
    counting (`rates.state_rates`), and so are the functions they are first to compile. A
    function that returned an array to them would leave it counted and never freed, and one
    compiled so, then called by counting code, would free arrays still in use: three more
    rounds of the elbow's and the squat jump's runs (monolithic, the reference and IMEX, in
    that order) must leave Numba's runtime holding no more arrays than before them."""
    runtime = compiled["runtime"]
    assert runtime["held_after"] == runtime["held_before"], runtime


def test_every_model_function_is_compiled_once(compiled):
    """Each torque-generator, activation and end-stop function is compiled for one
    signature, its offset an int64 (a literal or an omitted offset compiles it again)."""
    for module in ("torque_generator", "activation", "body"):
        for name, signatures in compiled[module].items():
            assert len(signatures) <= 1, (module, name, signatures)
            for signature in signatures:
                assert not any("Literal" in t or "omitted" in t for t in signature), \
                    (module, name, signature)


def test_the_collector_is_paused_while_numba_compiles_and_restored_after():
    """`torquesim.model.jit`: the garbage collector is off during a compilation (nested ones
    included), on again after it (also when typing fails), and left off if it was off."""
    import gc

    import numpy as np
    from numba.core import event

    from torquesim.model.jit import njit

    seen = []

    class Record(event.Listener):
        def on_start(self, _event):
            seen.append(gc.isenabled())

        def on_end(self, _event):
            pass

    @njit
    def inner(x):
        return x + 1.0

    @njit
    def outer(x):
        return inner(x) * 2.0

    @njit
    def untypable(x):
        return x.no_such_attribute

    assert gc.isenabled()
    with event.install_listener("numba:compile", Record()):
        assert outer(1.0) == 4.0
        assert seen == [False, False]  # outer, then inner while outer compiles
        assert gc.isenabled()
        with pytest.raises(Exception, match="no_such_attribute"):
            untypable(np.zeros(2))
        assert gc.isenabled()
        gc.disable()
        try:
            assert inner(np.float32(1.0)) == 2.0
            assert not gc.isenabled()
        finally:
            gc.enable()
