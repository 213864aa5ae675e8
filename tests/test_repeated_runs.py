"""Many runs of one warm model, as a fit makes them: what a repeated run keeps, and what it must not.

A run repeated on a warm model gives the same numbers, bit for bit, whether
its loop in C ran on the caller's thread (a short run), was stopped at its
deadline there and run again on a thread of its own (a long one), or was
called from another thread.  What a run keeps for the next — the spectrum of
the linearization at its start, the outcome of the stiffness check — is
kept per parameter values, start and span: another value in ``params=``,
another start or another span gets its own, so a stiff start still warns
after a start that was not.  Ctrl-C still stops a long run in C that does
not report its progress.  Nothing here is about speed
(``benchmarks/overhead.py`` measures it).
"""

import signal
import threading
import warnings

import numpy as np
import pytest

import lagrangian as lg
from lagrangian import compiled_loops, integrate, models
from lagrangian.numerics.problem import Problem

START = dict(initial={"theta_j1": 0.3, "theta_j2": -0.2}, velocity={"theta_j1": 0, "theta_j2": 0})


@pytest.fixture
def ctrl_c():
    """Python's own SIGINT handler for the test (a pytest-xdist worker starts with SIGINT ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(autouse=True)
def nothing_known_long(monkeypatch):
    """Each test starts with no kind of run known to be long (what earlier tests' runs taught the process)."""
    monkeypatch.setattr(compiled_loops, "_LONG", {})


@pytest.fixture
def loop_threads(monkeypatch):
    """The names of the threads the loops in C start, as they start them."""
    started = []

    class Counted(threading.Thread):
        def start(self):
            started.append(self.name)
            super().start()

    monkeypatch.setattr(compiled_loops.threading, "Thread", Counted)
    return started


def same(a, b):
    """Two results of one run: the same times, states, energies and notes, bit for bit."""
    assert a.t.tobytes() == b.t.tobytes()
    for name in a.q:
        assert a.q[name].tobytes() == b.q[name].tobytes()
        assert a.v[name].tobytes() == b.v[name].tobytes()
    for x, y in ((a.T, b.T), (a.V, b.V), (a.D, b.D)):
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes()
    assert a.notes == b.notes and a.nfev == b.nfev and a.method == b.method


def two_springs(k3=1e7):
    """Two unit masses on springs: one linear (1 rad/s), one cubic, whose rate at x_b = 1 is √(1 + 3·k3) (5.5e3 rad/s
    for k3 = 1e7) and at x_b = 0 is 1 rad/s: stiff or not by where it starts."""
    m = lg.Model("two springs")
    m.add("mass", "a", "a", m=1.0)
    m.add("spring", "ka", ("ground", "a"), k=1.0)
    m.add("mass", "b", "b", m=1.0)
    m.add("cubic_spring", "s", ("ground", "b"), k=1.0, k3=k3)
    return m


def stiff_warnings(m, x_b, t_end=1.0, **kwargs):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = m.simulate(t_end, initial={"x_a": 0.1, "x_b": x_b}, velocity={"x_a": 0.0, "x_b": 0.0}, rtol=1e-6,
                         points=3, **kwargs)
    said = [w for w in seen if issubclass(w.category, lg.StiffnessWarning)]
    noted = [n for n in res.notes if n.startswith("WARNING: model 'two springs' is stiff")]
    assert len(said) == len(noted)
    return [str(w.message) for w in said]


# -- the same numbers --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method, options", [("DOP853", {}), ("dopri5_c", {}), ("rk4_c", {"step": 1e-3}),
                                             ("DOP853_scipy", {})])
def test_a_repeated_run_gives_the_same_numbers(method, options):
    m = models.double_pendulum()
    first = m.simulate(0.5, **START, points=11, method=method, **options)
    for _ in range(3):
        same(m.simulate(0.5, **START, points=11, method=method, **options), first)
    fresh = models.double_pendulum().simulate(0.5, **START, points=11, method=method, **options)
    same(fresh, first)  # nothing kept from an earlier run changes a number


def test_a_short_run_in_c_starts_no_thread_and_one_with_progress_does(loop_threads):
    m = models.double_pendulum()
    first = m.simulate(1e-3, **START, points=2)
    assert "lagrangian-loop" not in loop_threads
    seen = []
    watched = m.simulate(1e-3, **START, points=2, progress=lambda t, end: seen.append(t))
    assert loop_threads.count("lagrangian-loop") == 1 and seen[-1] == 1e-3
    same(watched, first)


def test_a_run_stopped_at_its_deadline_runs_again_on_a_thread_with_the_same_numbers(monkeypatch, loop_threads):
    m = models.double_pendulum()
    straight = m.simulate(2.0, **START, points=21)
    assert "lagrangian-loop" not in loop_threads

    deadlines = []

    def passed(watch, seconds):  # its deadline passed before its first step
        deadlines.append(seconds)
        watch[1] = 1.0

    monkeypatch.setattr(compiled_loops._DEADLINES, "add", passed)
    m2 = models.double_pendulum()
    again = m2.simulate(2.0, **START, points=21)
    assert deadlines == [compiled_loops.SHORT] and loop_threads.count("lagrangian-loop") == 1
    same(again, straight)
    # a run of that method and span is known to be long now: straight to its own thread
    same(m2.simulate(2.0, **START, points=21), straight)
    assert len(deadlines) == 1 and loop_threads.count("lagrangian-loop") == 2


def test_a_fixed_step_run_known_to_be_long_goes_to_its_own_thread(loop_threads):
    m = models.double_pendulum()
    short = m.simulate(0.01, **START, points=3, method="rk4_c", step=1e-3)
    assert "lagrangian-loop" not in loop_threads
    steps = int(compiled_loops.SHORT_EVALUATIONS / 4) + 10
    long = m.simulate(steps * 1e-4, **START, points=3, method="rk4_c", step=1e-4)
    assert loop_threads.count("lagrangian-loop") == 1
    assert np.isfinite(long["theta_j1"]).all() and short.t.size == 3


def test_a_run_from_another_thread_runs_its_loop_there_with_the_same_numbers(loop_threads):
    m = models.double_pendulum()
    here = m.simulate(0.5, **START, points=11)
    out = {}
    worker = threading.Thread(target=lambda: out.setdefault("res", m.simulate(0.5, **START, points=11)))
    worker.start()
    worker.join()
    same(out["res"], here)
    assert "lagrangian-loop" not in loop_threads


def test_threads_sharing_a_model_get_the_same_numbers():
    m = models.double_pendulum()
    here = m.simulate(0.2, **START, points=5)
    results, errors = [], []

    def runs():
        try:
            for k in range(20):  # starts that come and go from what is kept
                results.append((k % 3, m.simulate(0.2, initial={"theta_j1": 0.3 + 0.1 * (k % 3), "theta_j2": -0.2},
                                                  velocity={"theta_j1": 0, "theta_j2": 0}, points=5)))
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    workers = [threading.Thread(target=runs) for _ in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert not errors and len(results) == 80
    for k, res in results:
        if k == 0:
            same(res, here)
        else:
            same(res, next(r for j, r in results if j == k))


def test_the_deadline_thread_stops_a_loop_past_its_deadline():
    """The process's deadline thread sets the stop flag of a registered loop once its deadline has passed, and
    leaves one removed in time alone."""
    late, early = np.zeros(2), np.zeros(2)
    done = threading.Event()
    compiled_loops._DEADLINES.add(late, 0.0)
    compiled_loops._DEADLINES.add(early, 3600.0)
    for _ in range(2000):
        if late[1]:
            break
        done.wait(0.005)
    compiled_loops._DEADLINES.remove(early)
    compiled_loops._DEADLINES.remove(late)
    assert late[1] == 1.0 and early[1] == 0.0


# -- what is kept, and for what -----------------------------------------------------------------------------------


def test_the_spectrum_is_kept_per_start_and_equals_a_fresh_one():
    m = models.double_pendulum()
    pb = Problem(m.numeric())
    for y in ([0.3, -0.2, 0.0, 0.0], [1.2, 0.4, 0.5, -1.0], [0.3, -0.2, 0.0, 0.0]):
        y = np.array(y)
        kept = pb.spectrum(0.0, y)
        again = pb.spectrum(0.0, y)
        fresh = Problem(m.numeric()).spectrum(0.0, y)
        for s in (again, fresh):
            assert s.eigenvalues.tobytes() == kept.eigenvalues.tobytes()
            assert s.zero.tolist() == kept.zero.tolist() and (s.scale, s.error) == (kept.scale, kept.error)
    a, b = pb.spectrum(0.0, np.array([0.3, -0.2, 0.0, 0.0])), pb.spectrum(0.0, np.array([1.2, 0.4, 0.5, -1.0]))
    assert a.eigenvalues.tobytes() != b.eigenvalues.tobytes()
    a.eigenvalues[:] = 0.0  # a caller's copy: what is kept stays as it was
    assert pb.spectrum(0.0, np.array([0.3, -0.2, 0.0, 0.0])).rho > 0


def test_a_stiff_start_warns_on_every_run_and_only_where_it_is_stiff(monkeypatch):
    # rates 1 and 5.5e3 rad/s from x_b = 1 (5.5e3 steps over 1 s, warned from 1e3 here); 1 and 1 from x_b = 0
    monkeypatch.setattr(integrate, "STIFFNESS_CHECK_STEPS", 1e3)
    m = two_springs()
    first = stiff_warnings(m, 1.0)
    assert len(first) == 1 and "5.48e+03" in first[0]
    assert stiff_warnings(m, 1.0) == first  # kept, and said again
    assert stiff_warnings(m, 0.0) == []  # another start: not stiff
    assert stiff_warnings(m, 1.0) == first
    assert stiff_warnings(m, 1.0, t_end=0.01) == []  # another span: 55 steps
    assert stiff_warnings(m, 1.0) == first
    assert stiff_warnings(m, 1.0, params={"k3_s": 1e-3}) == []  # other values: a soft spring
    assert stiff_warnings(m, 1.0) == first
    assert stiff_warnings(m, 1.0, compiled=False) == first  # evaluated by NumPy: the same advice
    monkeypatch.setattr(integrate, "STIFFNESS_CHECK_STEPS", 1e5)  # the threshold moved: judged again
    assert stiff_warnings(m, 1.0) == []


def test_a_refused_stiff_run_is_refused_every_time():
    m = lg.Model("damped")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=40)
    m.add("damper", "c", ("ground", "p"), c=1e7)  # decays at 3.3e7 1/s: 3.3e7 explicit steps over 1 s
    for _ in range(3):
        with pytest.raises(lg.IntegrationError, match="is stiff: its linearization at the start decays"):
            m.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    res = m.simulate(1.0, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, params={"c_c": 0.7}, points=3)
    assert res.t.size == 3


# -- interrupts ---------------------------------------------------------------------------------------------------


def speck():
    """A 1e-12 kg mass on a 137 N/m spring: some 3e8 evaluations over 0.7 s."""
    m = lg.Model("speck on a spring")
    m.add("mass", "m", "p", m=1e-12)
    m.add("spring", "k", ("ground", "p"), k=137.0)
    return m


@pytest.mark.parametrize("method", ["DOP853", "dopri5_c"])
@pytest.mark.slow
def test_a_long_run_in_c_without_progress_stops_on_an_interrupt(method, ctrl_c, loop_threads):
    """Without progress= the run starts on the caller's thread, passes its deadline, and goes on on a thread of its
    own, where Ctrl-C (``_thread.interrupt_main``) stops it as before."""
    import _thread

    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    try:
        with warnings.catch_warnings(), pytest.raises(KeyboardInterrupt):
            warnings.simplefilter("ignore", lg.StiffnessWarning)
            speck().simulate(0.7, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=1e12, method=method)
    finally:
        timer.cancel()
    assert loop_threads.count("lagrangian-loop") == 1


@pytest.mark.slow
def test_an_interrupt_during_the_first_part_of_a_run_stops_it_at_its_deadline(monkeypatch, ctrl_c):
    """Ctrl-C while the loop runs on the caller's thread takes effect when the loop returns there, at its deadline:
    the run is not begun again."""
    import _thread

    monkeypatch.setattr(compiled_loops, "SHORT", 1.0)
    again = []
    monkeypatch.setattr(compiled_loops, "_on_thread", lambda run, problem: again.append(run))
    timer = threading.Timer(0.2, _thread.interrupt_main)
    timer.start()
    try:
        with warnings.catch_warnings(), pytest.raises(KeyboardInterrupt):
            warnings.simplefilter("ignore", lg.StiffnessWarning)
            speck().simulate(0.7, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, max_evaluations=1e12)
    finally:
        timer.cancel()
    assert again == []


@pytest.mark.slow
def test_a_long_fixed_step_run_without_progress_stops_on_an_interrupt(ctrl_c):
    import _thread

    m = lg.Model("oscillator")
    m.add("mass", "m", "p", m=0.3)
    m.add("spring", "k", ("ground", "p"), k=47.0)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            m.simulate(50.0, step=1e-6, points=3, initial={"x_p": 1e-3}, velocity={"x_p": 0.0}, method="rk4_c",
                       energy_tol=False)  # 5e7 steps
    finally:
        timer.cancel()
