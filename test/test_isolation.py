"""Each pytest-xdist worker talks DDS on a domain of its own (conftest.py): two workers on
one domain made concurrent node tests hear each other's nodes."""
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def test_xdist_workers_get_distinct_domains(tmp_path: Path) -> None:
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_domains.py").write_text(
        "import os, pathlib, pytest\n"
        "@pytest.mark.parametrize('k', range(8))\n"
        "def test_domain(k):\n"
        "    worker = os.environ.get('PYTEST_XDIST_WORKER', 'main')\n"
        "    pathlib.Path(f'{worker}.domain').write_text(os.environ['ROS_DOMAIN_ID'])\n")
    env = {k: v for k, v in __import__("os").environ.items()
           if k not in ("ROS_DOMAIN_ID", "SWEEP_TEST_DOMAIN_BASE", "PYTEST_XDIST_WORKER")}
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p",
                           "no:cacheprovider", str(tmp_path)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    domains = {p.stem: p.read_text() for p in tmp_path.glob("*.domain")}
    assert set(domains) == {"gw0", "gw1"}, domains
    assert domains["gw0"] != domains["gw1"]
    assert all(1 <= int(d) <= 101 for d in domains.values())
