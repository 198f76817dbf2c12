"""Controllers are what they say (issue 24, item 5).

A controller file given to a scenario whose controller is ``none`` (open loop) or remote would
be loaded and never run: refused in one line. A saved DHP controller (``.json`` + ``.npz``) is
data from anywhere: every hostile variant is refused in one line naming the file and the field,
without hanging or reading without end (FIFOs and devices are refused before they are opened).
"""

import json
import os
import threading

import numpy as np
import pytest

from downhole.cli import main
from downhole.control.dhp import BitReference, DHPController
from downhole.control.dhp import load_controller as load_dhp_file
from downhole.errors import DownholeInputError
from downhole.sil.controllers import load_controller_file

NS, M, N = 40, 2, 4


def _saved(tmp_path, name="ctl"):
    """A small valid DHP controller saved as ``name.json`` + ``name.npz``; returns the stem."""
    rng = np.random.default_rng(5)
    c = DHPController(rng.normal(size=(NS, M)), rng.normal(size=(NS, M, N)),
                      rng.normal(size=(NS + 1, N)), rng.normal(size=(NS, M)),
                      np.array([1.0, 0.02, 1e3, 40.0]), np.array([0.1, 10.0]), 1e-3,
                      ["bit_axial_position", "bit_axial_velocity", "bit_angle",
                       "bit_angular_velocity"],
                      ["axial_position", "axial_velocity", "angular_position",
                       "angular_velocity"],
                      ["top_drive_axial_displacement", "top_drive_angle"], BitReference.step(),
                      input_limits=np.array([[-1.0, 1.0], [-50.0, 50.0]]),
                      arrays={"mu": np.ones(NS)})
    c.save(tmp_path / name)
    _ORIGINAL[str(tmp_path / name)] = c
    return tmp_path / name


_ORIGINAL: dict = {}  # the controllers as built, by saved stem


def _arrays(stem):
    with np.load(stem.with_suffix(".npz")) as d:
        return {k: d[k] for k in d.files}


def _bounded(fn, seconds=300.0):
    """Run ``fn`` in a thread; fail if it does not return within ``seconds`` (no hang: a bound
    for the event, far above a loaded machine's time, not a timing claim)."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed back to the test
            out["error"] = exc

    th = threading.Thread(target=run, daemon=True)
    th.start()
    th.join(seconds)
    assert not th.is_alive(), "the loader hung"
    return out


def _refused(path, field):
    out = _bounded(lambda: load_controller_file(path))
    exc = out.get("error")
    assert isinstance(exc, DownholeInputError), out
    msg = str(exc)
    assert "\n" not in msg and len(msg) < 400, msg
    assert field in msg, msg
    return msg


def test_a_valid_saved_controller_loads_and_matches_the_saved_one(tmp_path):
    stem = _saved(tmp_path)
    ours, theirs = load_dhp_file(stem.with_suffix(".json")), _ORIGINAL[str(stem)]
    z = np.array([0.01, 0.005, 3.0, 12.0])
    for k in (0, 17, NS - 1):
        np.testing.assert_array_equal(ours.control(k, z), theirs.control(k, z))
    assert ours.input_names == theirs.input_names and ours.dt == theirs.dt
    assert load_controller_file(stem.with_suffix(".npz")).n_steps == NS


@pytest.mark.parametrize("field, value, expect", [
    ("dt", 1e300, "dt"),
    ("dt", -1e-3, "dt"),
    ("dt", True, "dt"),
    ("dt", "1e-3", "dt"),
    ("format", "something/else", "format"),
    ("state_names", "bit_angle", "state_names"),
    ("state_kinds", ["axial_position"], "state_kinds"),
    ("input_names", [1, 2], "input_names.0"),
    ("past_horizon", "forever", "past_horizon"),
    ("stationary_step", NS, "stationary_step"),
    ("stationary_step", 2.5, "stationary_step"),
    ("reference", {"kind": "square"}, "reference"),
    ("reference", [1, 2], "reference"),
    ("meta", {"model": {"metadata": 5}}, "meta.model.metadata"),
    ("meta", {"integral": {"n_base": 99, "source": [0, 1]}}, "meta.integral.n_base"),
])
def test_hostile_json_fields_are_refused_by_name(tmp_path, field, value, expect):
    stem = _saved(tmp_path)
    js = stem.with_suffix(".json")
    meta = json.loads(js.read_text())
    meta[field] = value
    js.write_text(json.dumps(meta))
    msg = _refused(js, expect)
    assert str(js) in msg


@pytest.mark.parametrize("text, expect", [
    ("", "empty file"),
    ("   \n", "empty file"),
    ('{"format": "downhole.dhp_controller/1", "dt": 0.0', "truncated"),
    ('{"format": "downhole.dhp_controller/1", "dt": NaN}', "NaN"),
    ('{"dt": Infinity}', "Infinity"),
    ('{"dt": 1e400}', "dt"),
    ("[" * 100_000 + "]" * 100_000, "nested too deep"),
    ('{"a":' * 40 + "1" + "}" * 40, "nested deeper than 32"),
    ("[1, 2, 3]", "expected a JSON object"),
    ('{"dt": ' + "9" * 5000 + "}", "not valid JSON"),
    ("\udcff", "UTF-8"),
])
def test_truncated_empty_deep_or_non_finite_json_is_refused(tmp_path, text, expect):
    stem = _saved(tmp_path)
    js = stem.with_suffix(".json")
    js.write_bytes(text.encode("utf-8", "surrogateescape"))
    msg = _refused(js, expect)
    assert str(js) in msg


def _with_array(tmp_path, key, value, drop=()):
    stem = _saved(tmp_path)
    arrays = _arrays(stem)
    for k in drop:
        arrays.pop(k)
    if key is not None:
        arrays[key] = value
    np.savez(stem.with_suffix(".npz"), **arrays)
    return stem


@pytest.mark.parametrize("key, value, expect", [
    ("kd", np.zeros((NS, M, N), np.int8), "kd: dtype int8; expected float64"),
    ("kc", np.zeros((NS, M), complex), "kc: dtype complex128"),
    ("kd", np.full((NS, M, N), np.nan), "kd: non-finite"),
    ("u_ff", np.array([[0.0, np.inf]] * NS), "u_ff: non-finite"),
    ("kc", np.zeros((NS + 1, M)), "kc: shape"),
    ("kd", np.zeros((NS, M, N + 1)), "kd: shape"),
    ("kd", np.zeros((NS, M)), "kd"),
    ("reference_nd", np.zeros((NS, N)), "reference_nd: shape"),
    ("state_scale", np.array([1.0, 0.0, 1.0, 1.0]), "state_scale: expected positive"),
    ("input_limits", np.array([[1.0, -1.0], [0.0, 1.0]]), "input_limits"),
    ("extra_mu", np.array([1 + 2j]), "extra_mu: dtype complex128"),
    ("kd", np.array([{"a": 1}] * 3, dtype=object), "kd: Object arrays cannot be loaded"),
])
def test_hostile_arrays_are_refused_by_name(tmp_path, key, value, expect):
    stem = _with_array(tmp_path, key, value)
    msg = _refused(stem.with_suffix(".json"), expect)
    assert str(stem.with_suffix(".npz")) in msg


def test_a_missing_array_or_a_broken_archive_is_refused(tmp_path):
    stem = _with_array(tmp_path, None, None, drop=("kc",))
    _refused(stem.with_suffix(".npz"), "kc: missing")
    npz = stem.with_suffix(".npz")
    data = npz.read_bytes()
    npz.write_bytes(data[: len(data) // 2])  # truncated archive
    _refused(npz, "npz")
    npz.write_bytes(b"")
    _refused(npz, "not an npz archive")
    npz.unlink()
    _refused(stem.with_suffix(".json"), "file not found")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX FIFOs")
def test_a_fifo_or_a_device_named_json_is_refused_without_blocking(tmp_path):
    stem = _saved(tmp_path)
    js = stem.with_suffix(".json")
    js.unlink()
    os.mkfifo(js)  # opening it for reading would block until a writer comes
    _refused(js, "FIFO")
    js.unlink()
    if os.path.exists("/dev/zero"):
        js.symlink_to("/dev/zero")  # reading it would never end
        _refused(js, "device")
        js.unlink()
    js.mkdir()
    _refused(js, "directory")
    js.rmdir()
    _saved(tmp_path)
    npz = stem.with_suffix(".npz")
    npz.unlink()
    os.mkfifo(npz)
    _refused(js, "FIFO")


def test_an_oversized_file_is_refused_before_it_is_read(tmp_path, monkeypatch):
    import downhole.control.dhp.controller as mod

    stem = _saved(tmp_path)
    monkeypatch.setattr(mod, "MAX_DHP_JSON_BYTES", 100)
    _refused(stem.with_suffix(".json"), "at most 100 bytes")
    monkeypatch.setattr(mod, "MAX_DHP_JSON_BYTES", 1 << 20)
    monkeypatch.setattr(mod, "MAX_DHP_ARRAY_BYTES", 1000)
    _refused(stem.with_suffix(".json"), "decompressed")


# ------------------------------------------------------------------ the command line
def _scenario(tmp_path, controller):
    sc = tmp_path / "s.toml"
    sc.write_text(f'[model]\nfidelity = "lumped4"\n[controller]\n{controller}\n'
                  '[simulation]\nduration = "0.05 s"\n')
    return sc


def test_a_controller_file_with_an_open_loop_scenario_is_refused(tmp_path, capsys):
    stem = _saved(tmp_path, "trained")
    sc = _scenario(tmp_path, 'type = "none"')
    rc = main(["sil", str(sc), "--controller", str(stem.with_suffix(".json")), "--unpaced"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert 'type = "none"' in err and "would never run" in err and "trained.json" in err
    # the scenario naming a file while its type is none: the same
    sc.write_text(sc.read_text().replace('type = "none"',
                                         f'type = "none"\nfile = "{stem}.json"'))
    assert main(["sil", str(sc), "--unpaced"]) == 2
    assert "would never run" in capsys.readouterr().err
    # a file for a remote controller: it belongs to the other end
    sc = _scenario(tmp_path, 'type = "pi"\nremote = true')
    assert main(["sil", str(sc), "--controller", str(stem.with_suffix(".json"))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "downhole sil-controller --controller" in err
    # the open-loop scenario alone still runs
    sc = _scenario(tmp_path, 'type = "none"')
    assert main(["sil", str(sc), "--unpaced"]) == 0


def test_the_cli_refuses_a_hostile_controller_file_in_one_line(tmp_path, capsys):
    stem = _saved(tmp_path)
    js = stem.with_suffix(".json")
    meta = json.loads(js.read_text())
    meta["dt"] = 1e300
    js.write_text(json.dumps(meta))
    sc = _scenario(tmp_path, 'type = "pi"')
    assert main(["sil", str(sc), "--controller", str(js), "--unpaced"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{js}: dt: 1e+300" in err, err
    assert main(["sil-controller", "--controller", str(js), "--port", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "dt" in err
