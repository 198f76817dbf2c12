"""Seeded fuzz test of every scenario-reading path (issue 15, item 2).

Every ``examples/*.toml`` is mutated over the hostile-input classes that ``docs/scenarios.md``
promises to reject cleanly: non-finite, huge and overflowing numbers, ``"nan"`` quantities,
quantity strings with arithmetic, NUL characters, invalid UTF-8, over-long strings, wrong list
shapes and types, unknown keys and dropped keys. Each variant goes through the same loader and
validator its CLI command uses (in process; a few subprocess checks of the real CLI live in
``tests/test_scenario_hostile.py``) and must either validate or raise the project's input-error
class with the file (and for field mutations the field's table) in the message: no other
exception, no hang (a watchdog alarm per variant), and nothing written.
"""

from __future__ import annotations

import contextlib
import copy
import os
import random
import signal
import time
import tomllib
from pathlib import Path
from unittest import mock

import pytest
import tomli_w

from downhole.errors import DownholeInputError

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.toml"))
SEED = int(os.environ.get("DOWNHOLE_FUZZ_SEED", "20261201"))  # other seeds: hunt locally
VARIANTS_PER_EXAMPLE = int(os.environ.get("DOWNHOLE_FUZZ_VARIANTS", "24"))
WATCHDOG_S = 20  # s of CPU time of this process
WALL_BACKSTOP_S = 600  # s: only a variant blocked without using CPU reaches it


SLOW: list = []  # (seconds, variant): inspect with DOWNHOLE_FUZZ_SLOW=1


def teardown_module(module):
    if os.environ.get("DOWNHOLE_FUZZ_SLOW"):
        for sec, what in sorted(SLOW, reverse=True)[:10]:
            print(f"{sec:7.3f} s  {what}")


class _Hang(Exception):
    pass


class _Accepted(Exception):
    """Raised in place of running a sweep's cases: validation passed."""


@contextlib.contextmanager
def watchdog(seconds: int, what: str):
    """Catch a hang by structure, not by the wall clock: ``seconds`` of this process's CPU time
    (ITIMER_PROF: a loop that spins; other processes' load does not count), with a wall-clock
    backstop of ``WALL_BACKSTOP_S`` only for a variant that blocks without using CPU (a FIFO,
    a socket), far above any loaded machine's time for a refusal."""
    def _alarm(signum, frame):
        kind = "CPU" if signum == signal.SIGPROF else "wall-clock"
        raise _Hang(f"{what}: still running after {seconds if kind == 'CPU' else WALL_BACKSTOP_S}"
                    f" s of {kind} time")

    old_prof = signal.signal(signal.SIGPROF, _alarm)
    old_alrm = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    signal.alarm(WALL_BACKSTOP_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.alarm(0)
        signal.signal(signal.SIGPROF, old_prof)
        signal.signal(signal.SIGALRM, old_alrm)


# ------------------------------------------------------------------ the commands' entry points
def _simulate(path):
    from downhole.scenario import load_scenario, validate_data

    data, source, _ = load_scenario(path)
    validate_data(data, source)


def _sil(path):  # downhole sil, sil-controller --scenario and export-fmu
    from downhole.sil.scenario import load_sil_scenario

    load_sil_scenario(path)


def _dp(path):
    from downhole.scenario.system import load_dp_problem

    load_dp_problem(path)  # what `downhole optimize dp` reads (a preset or a described string)


def _design_dhp(path):
    from downhole.scenario.dhp import load_dhp_scenario

    load_dhp_scenario(path)


def _design_eid(path):
    from downhole.cli.design_eid import load_eid_scenario

    load_eid_scenario(path)


def _sweep(path):
    from downhole.sweep import runner

    with mock.patch.object(runner, "_execute", side_effect=_Accepted):
        try:
            runner.run_sweep(path, processes=1)
        except _Accepted:
            pass


def entry_points(name: str):
    """The loaders the commands reading this example call (all before any work starts)."""
    if name.startswith("sil_"):
        return [_sil]
    if name.startswith("dp_"):
        return [_dp]
    if name.startswith("dhp_"):
        return [_design_dhp, _simulate]
    if name.startswith("eid_"):
        return [_design_eid, _simulate]
    if name.startswith("sweep_"):
        return [_sweep]
    return [_simulate]


# ------------------------------------------------------------------ mutations
#: Values that no field accepts anywhere in a scenario.
ALWAYS_BAD = [float("inf"), float("-inf"), float("nan"), 1e308, -1e300, 10**30, -(10**40),
              "a\x00b", "x" * 5000, "\x07bell"]
#: Values that are wrong for most fields (accepted only where they happen to fit).
SOMETIMES_BAD = [-1.0, 0, 0.0, -1, "nan", "inf", "NaN m", "1e400 m", "1 s * 10**10**8",
                 "2**1000 m", "1 m**99", "(1 m)*(1 m)", "10 blorbs", "1e12 m", "1e300 N*m",
                 "-5 kg", "__import__('os')", True, [], {}, [[1, 2, 3]], [[0, "1 s * 10**9"]],
                 [1, [2, [3]]], "", " ", 1e-300, 2.5e9, 123456789]


def _leaves(node, path=()):
    """Every (path, value) below ``node``; paths are tuples of keys and list indices."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, path + (k,))
            yield path + (k,), v
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _leaves(v, path + (i,))
            yield path + (i,), v


def _tables(node, path=()):
    if isinstance(node, dict):
        yield path, node
        for k, v in node.items():
            yield from _tables(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _tables(v, path + (i,))


def _set(data, path, value):
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value


def _delete(data, path):
    node = data
    for p in path[:-1]:
        node = node[p]
    del node[path[-1]]


def make_variants(data: dict, text: str, rng: random.Random, n: int):
    """``n`` mutated variants: ``(label, bytes, must_reject, table)`` where ``table`` is the
    top-level key the error must name (None for file-level damage)."""
    out = []
    for k in range(n):
        kind = k % 8
        d = copy.deepcopy(data)
        leaves = list(_leaves(d))
        tables = list(_tables(d))
        if kind in (0, 1):           # a value no field accepts
            path, _ = rng.choice(leaves)
            value = rng.choice(ALWAYS_BAD)
            _set(d, path, value)
            out.append((f"{'.'.join(map(str, path))} = {value!r:.40}", d, True, path[0]))
        elif kind in (2, 3, 4):      # a value wrong for most fields
            path, _ = rng.choice(leaves)
            value = rng.choice(SOMETIMES_BAD)
            _set(d, path, value)
            out.append((f"{'.'.join(map(str, path))} = {value!r:.40}", d, False, path[0]))
        elif kind == 5:              # an unknown key in some table, or a dropped key
            tpath, table = rng.choice(tables)
            if rng.random() < 0.5 or not table:
                table["definitely_not_a_key"] = 1.0
                top = tpath[0] if tpath else "definitely_not_a_key"
                out.append((f"unknown key in {'.'.join(map(str, tpath)) or '<top>'}", d,
                            not str(top).startswith("sweep"), top))
            else:
                key = rng.choice(sorted(table))
                _delete(d, tpath + (key,))
                out.append((f"dropped {'.'.join(map(str, tpath + (key,)))}", d, False,
                            (tpath + (key,))[0]))
        elif kind == 6:              # wrong shape: a table or list replaced, a scalar wrapped
            path, value = rng.choice(leaves)
            if isinstance(value, (dict, list)):
                new = rng.choice([1.0, "x", [[1.0]], [1.0, 2.0, 3.0], [[0.0, 1.0, 2.0]]])
            else:
                new = rng.choice([[value], [[value]], {"v": value}, [value, value, value]])
            _set(d, path, new)
            out.append((f"{'.'.join(map(str, path))} reshaped to {new!r:.40}", d, False,
                        path[0]))
        else:                        # damage to the bytes themselves
            raw = text.encode()
            pos = rng.randrange(len(raw))
            choice = rng.randrange(4)
            if choice == 0:
                blob = raw[:pos] + b"\xff\xfe\xc3(" + raw[pos:]
                label, bad = "invalid UTF-8", True
            elif choice == 1:
                blob = raw[:pos] + b"\x00" + raw[pos:]
                label, bad = "NUL byte", True
            elif choice == 2:
                blob = raw + b"\nzz_huge = " + b"9" * 5000 + b"\n"
                label, bad = "5000-digit integer", True
            else:
                blob = raw[:pos]
                label, bad = f"truncated at byte {pos}", False
            out.append((label, blob, bad, None))
            continue
        out[-1] = out[-1][:1] + (tomli_w.dumps(d).encode(),) + out[-1][2:]
    return out


def _check_variant(entry, path: Path, label: str, must_reject: bool, table, workdir: Path):
    before = sorted(os.listdir(workdir))
    what = f"{entry.__name__} on {path.name} [{label}]"
    t0 = time.perf_counter()
    try:
        with watchdog(WATCHDOG_S, what):
            entry(path)
    except _Hang:
        raise
    except DownholeInputError as exc:
        msg = str(exc)
        assert "\n" not in msg.strip(), f"{what}: multi-line error {msg!r}"
        assert str(path) in msg, f"{what}: the error does not name the file: {msg!r}"
        if table is not None and not str(table).startswith("sweep"):
            tail = msg.split(str(path), 1)[1]
            # "FILE: dotted.field: what was expected"; a cross-field check may name a sibling
            # field, and a few checks name the field inside the message ("FILE: a.b = ...")
            names_field = tail.startswith(": ") and len(tail.split(": ")) >= 3
            assert names_field or str(table) in tail, \
                f"{what}: the error names no field: {msg!r}"
        rejected = True
    except Exception as exc:
        pytest.fail(f"{what}: {type(exc).__name__}: {exc}")
    else:
        rejected = False
    SLOW.append((time.perf_counter() - t0, what))
    assert sorted(os.listdir(workdir)) == before, f"{what}: wrote files"
    if must_reject:
        assert rejected, f"{what}: hostile value was accepted"
    return rejected


@pytest.fixture()
def in_empty_dir(tmp_path, monkeypatch):
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    return work


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.name)
def test_examples_validate(example, in_empty_dir):
    """Every example passes every entry point that reads it (the fuzz baseline)."""
    for entry in entry_points(example.name):
        with watchdog(60, f"{entry.__name__} {example.name}"):
            entry(example)
    assert os.listdir(in_empty_dir) == []


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.name)
def test_fuzzed_examples_fail_cleanly(example, in_empty_dir, tmp_path):
    """Seeded variants of each example: validated or one clean input error, never anything
    else, never a hang, nothing written."""
    text = example.read_text()
    data = tomllib.loads(text)
    rng = random.Random(f"{SEED}:{example.name}")
    variants = make_variants(data, text, rng, VARIANTS_PER_EXAMPLE)
    vdir = tmp_path / "variants"
    vdir.mkdir()
    # relative paths inside examples (survey CSV, controller files) resolve next to the file
    for extra in example.parent.glob("*.csv"):
        (vdir / extra.name).write_bytes(extra.read_bytes())
    rejected = 0
    for i, (label, blob, must_reject, table) in enumerate(variants):
        path = vdir / f"v{i:02d}_{example.name}"
        path.write_bytes(blob)
        for entry in entry_points(example.name):
            rejected += _check_variant(entry, path, label, must_reject, table, in_empty_dir)
    assert rejected >= VARIANTS_PER_EXAMPLE // 4  # the mutations do bite
