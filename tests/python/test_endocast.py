"""The Python module `endocast` (python/): extract from a path and an array, the same bytes as the
CLI, the mesh tools, progress and interruption, and bad input as Python exceptions."""
import doctest
import hashlib
import json
import os
import pathlib
import re
import subprocess
import sys
import threading

import numpy as np
import pytest

import endocast

CLI = os.environ.get("ENDOCAST_CLI", "endocast")
SHARED = pathlib.Path(os.environ.get("ENDOCAST_SHARED_DATA", "../shared/data"))
SOURCE = pathlib.Path(os.environ.get("ENDOCAST_SOURCE_DIR", pathlib.Path(__file__).parents[2]))
CTHEAD = SHARED / "cthead" / "cthead.nhdr"


def md5(path):
    return hashlib.md5(pathlib.Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def skull():
    """The human phantom at 2 mm: 87 x 104 x 82 voxels, with its true ECV."""
    return endocast.phantom("human", spacing=2.0)


@pytest.fixture(scope="module")
def skull_nrrd(tmp_path_factory):
    """The same phantom written by the CLI, with its truth."""
    d = tmp_path_factory.mktemp("phantom")
    subprocess.run([CLI, "-q", "phantom", str(d / "p.nrrd"), "--spacing", "2", "2", "2"], check=True)
    return d / "p.nrrd", json.loads((d / "p.json").read_text())


def test_extract_from_an_array_is_near_the_truth(skull):
    r = endocast.extract(skull.array, spacing=skull.spacing, origin=skull.origin)
    assert abs(r.ecv_ml / skull.true_ecv_ml - 1) < 0.02
    assert r.mesh.vertices.shape[1] == 3 and r.mesh.vertices.dtype == np.float64
    assert r.mesh.faces.shape[1] == 3 and r.mesh.faces.dtype == np.uint32
    assert r.mask.shape == skull.array.shape and r.mask.dtype == np.uint8
    voxel_ml = np.prod(skull.spacing) / 1000
    assert r.mask.sum() * voxel_ml == pytest.approx(r.report["mask_volume_ml"], rel=1e-9)
    assert r.report["closed_manifold"] and r.report["self_intersections"] == 0
    assert r.report["ecv_ml"] == r.ecv_ml
    assert r.report["lengths_mm"] and set(r.report["lengths_mm"]) == set(r.report["length_rules"])
    assert endocast.inspect(r.mesh)["closed_manifold"]


def test_python_and_cli_give_the_same_mesh_bytes(skull_nrrd, tmp_path):
    path, truth = skull_nrrd
    iso = truth["suggested_iso"]
    subprocess.run([CLI, "-q", "extract", str(path), "--iso", str(iso), "-o", str(tmp_path / "cli.ply"),
                    "--report", str(tmp_path / "cli.json")], check=True)
    by_path = endocast.extract(path, iso=iso)
    by_path.mesh.write(tmp_path / "path.ply")
    v = endocast.read_volume(path)
    by_array = endocast.extract(v.array, spacing=v.spacing, origin=v.origin, direction=v.direction, iso=iso)
    by_array.mesh.write(tmp_path / "array.ply")
    assert md5(tmp_path / "cli.ply") == md5(tmp_path / "path.ply") == md5(tmp_path / "array.ply")
    cli = json.loads((tmp_path / "cli.json").read_text())
    assert cli["ecv_ml"] == by_path.ecv_ml == by_array.ecv_ml
    for key in ("isovalue", "bone_contact", "lengths_mm", "openings", "genus", "warnings"):
        assert cli[key] == by_path.report[key], key


@pytest.mark.skipif(not CTHEAD.exists(), reason="../shared/data/cthead absent")
def test_cthead_the_same_in_python_and_the_cli(tmp_path):
    subprocess.run([CLI, "-q", "extract", str(CTHEAD), "-o", str(tmp_path / "cli.ply")], check=True)
    r = endocast.extract(CTHEAD)
    r.mesh.write(tmp_path / "py.ply")
    assert md5(tmp_path / "cli.ply") == md5(tmp_path / "py.ply")


def test_a_volume_and_an_int16_array_give_the_same_result(skull):
    a = endocast.extract(skull, iso=skull.suggested_iso)
    b = endocast.extract(skull.array.astype(np.float32), spacing=skull.spacing, origin=skull.origin,
                         iso=skull.suggested_iso)
    assert a.ecv_ml == b.ecv_ml
    assert np.array_equal(a.mesh.faces, b.mesh.faces) and np.array_equal(a.mesh.vertices, b.mesh.vertices)


def test_progress_reports_each_stage_and_its_exception_stops_the_run(skull):
    events = []
    endocast.extract(skull, progress=lambda e, text: events.append((e, text)))
    stages = [t for e, t in events if e == "stage"]
    assert stages[0] == "read" and "watershed" in stages and stages[-1] == "check"

    def stop(event, text):
        if text == "distance":
            raise RuntimeError("stopped by the callback")

    with pytest.raises(RuntimeError, match="stopped by the callback"):
        endocast.extract(skull, progress=stop)


def test_a_pending_signal_interrupts_the_run(skull):
    import signal

    def interrupt(event, text):
        if text == "seeds":
            signal.raise_signal(signal.SIGINT)

    with pytest.raises(KeyboardInterrupt):
        endocast.extract(skull, progress=interrupt)


def test_the_work_runs_without_the_gil(skull):
    ticks = []
    done = threading.Event()

    def run():
        endocast.extract(skull)
        done.set()

    t = threading.Thread(target=run)
    t.start()
    while not done.is_set():
        ticks.append(1)  # Python code running while extract works
        done.wait(0.001)
    t.join()
    assert len(ticks) > 3


@pytest.mark.parametrize("make,error", [
    (lambda a: a.astype(np.complex64), TypeError),
    (lambda a: a.astype(bool), TypeError),
    (lambda a: a[0], ValueError),
    (lambda a: np.where(np.arange(a.size).reshape(a.shape) == 5000, np.nan, a.astype(np.float32)), ValueError),
])
def test_bad_arrays_raise(skull, make, error, tmp_path):
    with pytest.raises(error):
        endocast.extract(make(skull.array), spacing=skull.spacing)


def test_bad_values_raise_value_errors(skull):
    with pytest.raises(ValueError, match="spacing"):
        endocast.extract(skull.array, spacing=(2, -2, 2))
    with pytest.raises(ValueError, match="spacing"):
        endocast.extract(skull.array)
    with pytest.raises(ValueError, match="downsample"):
        endocast.extract(skull, downsample=0)
    with pytest.raises(ValueError, match="seed_mode"):
        endocast.extract(skull, seed_mode="everywhere")
    with pytest.raises(endocast.ParameterError, match="unknown option"):
        endocast.extract(skull, isovalue=300)


def test_missing_files_and_unreadable_input(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        endocast.extract(tmp_path / "absent.nrrd")
    bad = tmp_path / "bad.nrrd"
    bad.write_bytes(b"NRRD0004\ntype: short\ndimension: 3\nsizes: 10 10 10\nencoding: raw\n\n" + b"\0" * 100)
    with pytest.raises(endocast.InputError) as e:
        endocast.extract(bad)
    assert isinstance(e.value, OSError) and "bad.nrrd" in str(e.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.nrrd"]  # nothing written


def test_no_cavity_is_the_projects_own_error():
    solid = np.full((40, 40, 40), 2000, dtype=np.int16)
    with pytest.raises(endocast.NoResultError):
        endocast.extract(solid, spacing=(1, 1, 1), iso=300)


def test_mesh_tools(skull, tmp_path):
    r = endocast.extract(skull)
    r.mesh.write(tmp_path / "m.stl")
    m = endocast.read_mesh(tmp_path / "m.stl")
    assert len(m.faces) == len(r.mesh.faces)
    assert endocast.compare(m, r.mesh)["hausdorff"] < 1e-3
    small, info = endocast.simplify(r.mesh, ratio=0.25)
    assert len(small.faces) <= 0.26 * len(r.mesh.faces)
    checks = endocast.inspect(small)
    assert checks["closed_manifold"] and checks["self_intersections"] == 0
    assert checks["volume_ml"] == pytest.approx(r.ecv_ml, rel=0.01)
    assert info["hausdorff_mm"] <= 0.35 + 1e-9
    with pytest.raises(FileNotFoundError):
        endocast.read_mesh(tmp_path / "absent.ply")


def test_readme_python_example_runs():
    text = (SOURCE / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README.md has no ```python block"
    test = doctest.DocTestParser().get_doctest(blocks[0], {}, "README", "README.md", 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    runner.run(test)
    assert runner.failures == 0 and runner.tries > 0


def test_module_docstring_example_runs():
    failures, tries = doctest.testmod(endocast, optionflags=doctest.ELLIPSIS)
    assert failures == 0 and tries > 0


def test_the_python_example_plots_a_batch(tmp_path):
    pytest.importorskip("matplotlib")
    example = SOURCE / "examples" / "python" / "ecv_batch.py"
    out = subprocess.run([sys.executable, str(example), "--phantoms", str(tmp_path / "ecv.png")],
                         check=True, capture_output=True, text=True).stdout
    assert (tmp_path / "ecv.png").stat().st_size > 1000
    rows = (tmp_path / "ecv.csv").read_text().splitlines()
    assert rows[0] == "specimen,ecv_ml,bone_contact,warnings" and len(rows) == 4
    assert out.count("truth") == 3


def test_warnings_are_typed(skull):
    """A scan cropped through the braincase: the cavity meets the border (its ECV a lower bound)."""
    z = skull.array.shape[0] * 55 // 100
    r = endocast.extract(skull, crop=(0, 0, 0, skull.array.shape[2], skull.array.shape[1], z))
    codes = [w.code for w in r.warnings]
    assert "border_contact" in codes
    w = r.warnings[codes.index("border_contact")]
    assert w.values["border_contact_mm2"] > 0 and "volume border" in w
    assert r.report["warnings"] == list(r.warnings)
    assert [d["code"] for d in r.report["warning_details"]] == codes
    assert endocast.extract(skull).warnings == []
