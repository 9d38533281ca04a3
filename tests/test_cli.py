import subprocess
import sys

import train


def test_demo_prints_a_table_where_lqr_beats_free_drift(capsys):
    assert train.main(["demo", "--seeds", "2"]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if line.startswith(("zero", "lqr"))}
    assert set(rows) == {"zero", "lqr-zoh", "lqr-continuous"}
    assert rows["lqr-zoh"] < 0.5 * rows["zero"]
    assert rows["lqr-zoh"] <= rows["lqr-continuous"] * 1.001  # the sampled-data optimum is no worse


def test_bad_preset_is_a_one_line_error_with_exit_code_2():
    proc = subprocess.run([sys.executable, "train.py", "demo", "--preset", "nope"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "preset must be one of ['spec-000', 'spec-001']" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_unknown_reproduction_is_rejected():
    assert train.main(["reproduce", "no-such-paper"]) == 2
