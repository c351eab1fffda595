"""``scripts/slow_tests.py``: the slow list made from a JUnit report."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_the_slow_list_names_the_tests_at_or_over_the_threshold(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("slow_tests", ROOT / "scripts" / "slow_tests.py")
    slow_tests = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(slow_tests)
    report = tmp_path / "junit.xml"
    report.write_text(
        '<testsuites><testsuite>'
        '<testcase classname="tests.shading.test_accel" name="test_a[x-1]" time="0.7"/>'
        '<testcase classname="tests.shading.test_accel" name="test_b" time="0.2"/>'
        '<testcase classname="tests.test_render.TestGroup" name="test_c" time="3.0"/>'
        '<testcase classname="tests.test_render" name="test_d" time="9.0"><skipped/></testcase>'
        '</testsuite></testsuites>')
    out = tmp_path / "slow.txt"
    monkeypatch.setattr(slow_tests, "OUT", out)
    monkeypatch.setattr(slow_tests, "THRESHOLD_S", 0.5)
    assert slow_tests.main([str(report)]) == 0
    listed = [line for line in out.read_text().splitlines() if not line.startswith("#")]
    assert listed == ["tests/shading/test_accel.py::test_a[x-1]", "tests/test_render.py::TestGroup::test_c"]
