"""Worker processes from a plain script: an unguarded call is refused with a clear error before
any process starts (and nothing is written); the guarded script works; a pool that breaks anyway
raises instead of returning NaN / "every experiment failed"."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from downhole._workers import GUARD, check_main_guarded
from downhole.errors import DownholeInputError, WorkerProcessError

ROOT = Path(__file__).resolve().parents[1]

SWEEP = '''
from downhole.sweep import run_sweep, save_sweep

BASE = {"model": {"fidelity": "lumped4", "preset": "table_2_1"},
        "operation": {"rop": "10 mm/s", "surface_speed": "10 rad/s"},
        "simulation": {"duration": "2 s", "dt": "1 ms", "integrator": "newmark",
                       "record_dt": "10 ms"}}
'''
CALL = '''ds = run_sweep(BASE, ["operation.surface_speed=8,12"], ["mean_bit_angular_velocity"],
               processes=2)
save_sweep(ds, "sweep.nc")
print("values", [round(float(v), 3) for v in ds["mean_bit_angular_velocity"].values])
'''


def _run(script: Path, cwd: Path, timeout=300):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               MPLBACKEND="Agg")
    return subprocess.run([sys.executable, str(script)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def test_unguarded_run_sweep_script_fails_clearly_and_writes_nothing(tmp_path):
    script = tmp_path / "sweep_script.py"
    script.write_text(SWEEP + CALL)
    p = _run(script, tmp_path)
    assert p.returncode != 0
    last = p.stderr.strip().splitlines()[-1]
    assert "DownholeInputError" in last and "run_sweep(processes=2)" in last
    assert GUARD in last and "processes=1" in last and "sweep_script.py, line" in last
    assert "BrokenProcessPool" not in p.stderr and "bootstrapping" not in p.stderr
    assert not (tmp_path / "sweep.nc").exists()
    assert "values" not in p.stdout


@pytest.mark.slow
def test_guarded_run_sweep_script_runs_on_two_processes(tmp_path):
    script = tmp_path / "sweep_script.py"
    script.write_text(SWEEP + "\n" + GUARD + "\n" + textwrap.indent(CALL, "    "))
    p = _run(script, tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "sweep.nc").exists()
    values = [float(v) for v in p.stdout.split("values", 1)[1].strip(" []\n").split(",")]
    assert len(values) == 2 and all(v == v for v in values)  # no NaN
    # 2 s from rest: the mean bit speed over the second second lags but follows the set-point
    assert values[0] < values[1]


def test_unguarded_reproduce_script_fails_before_writing(tmp_path):
    script = tmp_path / "repro.py"
    script.write_text('from downhole.report import reproduce\n'
                      'reproduce(["fig2.3", "fig3.4"], "out/some", quick=True, jobs=2)\n')
    p = _run(script, tmp_path)
    assert p.returncode != 0
    last = p.stderr.strip().splitlines()[-1]
    assert "reproduce(jobs=2)" in last and GUARD in last and "jobs=1" in last
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ the detection, in-process
def _exec_as_main(tmp_path, body: str):
    """Run ``body`` as the main script would (its frame's globals are __main__'s)."""
    path = tmp_path / "main_script.py"
    path.write_text(body)
    code = compile(body, str(path), "exec")
    main = sys.modules["__main__"]
    saved = dict(vars(main))
    try:
        vars(main).update(__name__="__main__", __file__=str(path), __spec__=None,
                          check=check_main_guarded)
        exec(code, vars(main))
    finally:
        vars(main).clear()
        vars(main).update(saved)


@pytest.mark.parametrize("body", [
    'if __name__ == "__main__":\n    check("f(jobs=2)", "jobs=1")\n',
    "if '__main__' == __name__:\n    x = 1\n    check('f(jobs=2)', 'jobs=1')\n",
    'def main():\n    check("f(jobs=2)", "jobs=1")\n\nif __name__ == "__main__":\n    main()\n',
])
def test_guarded_calls_pass(tmp_path, body):
    _exec_as_main(tmp_path, body)


@pytest.mark.parametrize("body", [
    'check("f(jobs=2)", "jobs=1")\n',
    'def main():\n    check("f(jobs=2)", "jobs=1")\n\nmain()\n',
    'if __name__ != "__main__":\n    pass\nelse:\n    check("f(jobs=2)", "jobs=1")\n',
    'if True:\n    check("f(jobs=2)", "jobs=1")\n',
])
def test_unguarded_calls_are_refused(tmp_path, body):
    with pytest.raises(DownholeInputError, match=r"main_script.py, line \d+: f\(jobs=2\) "
                                                 r"starts worker processes"):
        _exec_as_main(tmp_path, body)


def test_a_worker_reimporting_the_script_is_refused(tmp_path):
    body = 'check("f(jobs=2)", "jobs=1")\n'
    g = {"__name__": "__mp_main__", "__file__": str(tmp_path / "s.py"),
         "check": check_main_guarded}
    with pytest.raises(DownholeInputError, match="ran again while a worker process imported"):
        exec(compile(body, str(tmp_path / "s.py"), "exec"), g)


def test_a_package_main_or_a_notebook_is_not_reimported(tmp_path):
    # python -m pkg (pkg/__main__.py): spawn does not run it again, so no guard is needed
    pkg = tmp_path / "mypkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "__main__.py").write_text("from downhole._workers import check_main_guarded\n"
                                     "check_main_guarded('f(jobs=2)', 'jobs=1')\nprint('ok')\n")
    p = subprocess.run([sys.executable, "-m", "mypkg"], cwd=tmp_path,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                       text=True, timeout=120)
    assert p.stdout.strip() == "ok", p.stderr
    # python -m module (a plain module run as main) is imported again: refused
    (tmp_path / "mymod.py").write_text("from downhole._workers import check_main_guarded\n"
                                       "check_main_guarded('f(jobs=2)', 'jobs=1')\n")
    p = subprocess.run([sys.executable, "-m", "mymod"], cwd=tmp_path,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                       text=True, timeout=120)
    assert p.returncode != 0 and "mymod.py, line 2: f(jobs=2) starts worker" in p.stderr


def test_no_main_script_passes():
    check_main_guarded("f(jobs=2)", "jobs=1")  # called from pytest's guarded entry point
    p = subprocess.run([sys.executable, "-c", "from downhole._workers import check_main_guarded;"
                        " check_main_guarded('f', 'jobs=1'); print('ok')"],
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                       text=True, timeout=120)
    assert p.stdout.strip() == "ok", p.stderr


# ------------------------------------------------------------------ a pool that breaks anyway
PLUGIN = '''
import os
from downhole.experiments import experiment

@experiment("test.worker_dies", title="a worker that dies", chapter=3, claim="never")
def _dies(out_dir, quick):
    os._exit(3)  # the worker process is gone, as if the system had killed it

@experiment("test.worker_ok", title="fine", chapter=3, claim="1 + 1 = 2")
def _ok(out_dir, quick):
    return {"measured": {"sum": 2}, "passed": True}
'''


def test_a_broken_pool_raises_instead_of_returning(tmp_path):
    (tmp_path / "dh_dying_experiments.py").write_text(PLUGIN)
    script = tmp_path / "repro.py"
    script.write_text('from downhole.report import reproduce\n'
                      'if __name__ == "__main__":\n'
                      '    s = reproduce(["test.worker_dies", "test.worker_ok"], "out", '
                      'quick=True, jobs=2)\n'
                      '    print("returned", s)\n')
    env = dict(os.environ, PYTHONPATH=f"{ROOT}{os.pathsep}{tmp_path}",
               DOWNHOLE_EXPERIMENT_PLUGINS="dh_dying_experiments", MPLBACKEND="Agg")
    p = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode != 0 and "returned" not in p.stdout
    last = p.stderr.strip().splitlines()[-1]
    assert WorkerProcessError.__name__ in last and "reproduce(jobs=2)" in last
    assert "process pool broke" in last
    assert (tmp_path / "out" / "INCOMPLETE").exists()  # the run is marked unfinished
