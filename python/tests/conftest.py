"""Where the tests find the project, the built command line and a scratch folder (ctest sets the
environment: python/CMakeLists.txt)."""

import json
import os
import pathlib
import subprocess

import pytest

SOURCE = pathlib.Path(os.environ.get("FURNIHOST_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BINARY = os.environ.get("FURNIHOST_BINARY", str(SOURCE / "build" / "bin" / "furnihost"))
SHARED = SOURCE.parent / "shared" / "data"


def shared_file(*parts):
    """A file of ../shared/data; the test fails (never skips) when it is missing."""
    path = SHARED.joinpath(*parts)
    assert path.is_file(), f"shared data missing: {path} (CI must have ../shared beside the clone)"
    return path


def run_cli(*args, check=True):
    """Runs the furnihost binary; returns the CompletedProcess (text)."""
    r = subprocess.run([BINARY, *map(str, args)], capture_output=True, text=True, stdin=subprocess.DEVNULL)
    if check:
        assert r.returncode == 0, f"furnihost {' '.join(map(str, args))}: exit {r.returncode}\n{r.stderr[-2000:]}"
    return r


def cli_detections(scan, graph, out, *extra):
    """The detections.json the command line writes for `scan`."""
    run_cli("--graph", graph, "-q", "--out", out, *extra, scan)
    return json.loads((pathlib.Path(out) / "detections.json").read_text())


@pytest.fixture
def out_dir(tmp_path):
    return tmp_path
