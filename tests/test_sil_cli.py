"""The SIL CLI: ``downhole sil`` in-process and with a remote controller process, bad input."""

import json
import subprocess
import sys

import pytest

from downhole.cli import main
from downhole.sil.testing import free_port
from downhole.sim.result import load_result


def test_sil_runs_a_scenario_unpaced_and_writes_a_result(tmp_path, capsys):
    out = tmp_path / "run.nc"
    rc = main(["sil", "examples/sil_pi_hybrid68.toml", "--duration", "1", "--unpaced",
               "--out", str(out)])
    assert rc == 0
    stats = json.loads(capsys.readouterr().out)["stats"]
    assert stats["steps"] == 1000
    res = load_result(out)
    assert res.time[-1] == pytest.approx(1.0)
    assert "command_hook_load" in res and res.attrs["controller"] == "SurfacePI"


def test_sil_remote_with_the_controller_client_command(tmp_path):
    port = free_port()
    ctrl = tmp_path / "c.py"
    ctrl.write_text("from downhole.sil import pi_controller_for, build_plant\n"
                    "controller = pi_controller_for(build_plant('hybrid68'))\n")
    client = subprocess.Popen([sys.executable, "-c", "import sys; from downhole.cli import main;"
                               " sys.exit(main(sys.argv[1:]))", "sil-controller", "--port",
                               str(port), "--controller", str(ctrl), "--allow-code",
                               "--idle-timeout", "2"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        rc = main(["sil", "examples/sil_pi_hybrid68.toml", "--remote", "--port", str(port),
                   "--duration", "1", "--out", str(tmp_path / "r.nc")])
        out, _ = client.communicate(timeout=60)
    finally:
        client.kill()
    assert rc == 0
    sent = json.loads(out.strip().splitlines()[-1])["commands_sent"]
    assert 950 <= sent <= 1000  # one per step; a step whose observation was overtaken is skipped
    assert load_result(tmp_path / "r.nc").attrs["controller"] == "remote"


def test_bad_inputs_exit_2(tmp_path, capsys):
    assert main(["sil", str(tmp_path / "missing.toml")]) == 2
    assert "file not found" in capsys.readouterr().err
    assert main(["sil-controller", "--port", "1"]) == 2
