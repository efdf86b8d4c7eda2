"""Batch runs on a Dask LocalCluster: the same bytes as the local pool; dead workers retried."""

import pytest
from batch_fakes import fake_pipeline, good_sessions, make_study

from motionlab.batch import load_manifest, run_study
from motionlab.errors import InputError

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def scheduler():
    # the scheduler gives up on a task at the first dead worker: motionlab's --retry takes over
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        )
    yield cluster.scheduler_address
    cluster.close()


def test_dask_gives_the_bytes_of_the_local_pool(tmp_path, scheduler):
    manifest = make_study(tmp_path, good_sessions(3) | {("S9", "v1"): "corrupt"})
    study = load_manifest(manifest)
    local = run_study(study, tmp_path / "local", workers=2, pipeline=fake_pipeline)
    on_dask = run_study(study, tmp_path / "dask", scheduler=scheduler, pipeline=fake_pipeline)
    assert [o.status for o in on_dask.outcomes] == [o.status for o in local.outcomes]
    assert on_dask.outcomes[-1].error == local.outcomes[-1].error
    for name in ("study_metrics.csv", "study_failures.csv"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "local" / name).read_bytes()
    again = run_study(study, tmp_path / "dask", scheduler=scheduler, pipeline=fake_pipeline)
    assert again.count("skipped") == 6


def test_dask_resubmits_after_a_killed_worker(tmp_path, scheduler):
    sessions = good_sessions(1) | {("S8", "v1"): "crash 0 40 2", ("S8", "v2"): "crash-always 1"}
    study = load_manifest(make_study(tmp_path, sessions))
    result = run_study(
        study, tmp_path / "out", scheduler=scheduler, retry=1, pipeline=fake_pipeline
    )
    got = {(o.subject, o.visit): (o.status, o.kind, o.attempts) for o in result.outcomes}
    assert got["S8", "v1"] == ("done", "", 2)
    assert got["S8", "v2"] == ("failed", "worker_died", 2)
    assert got["S1", "v1"][0] == got["S1", "v2"][0] == "done"


def test_unreachable_scheduler_is_an_input_error(tmp_path, monkeypatch):
    """... told before the study folder is made or a progress line drawn (the real trunk study
    printed a '0/5' bar above the error and left a folder holding only the marker)."""
    monkeypatch.setattr("motionlab.batch.runner._CONNECT_TIMEOUT_S", 0.5)
    study = load_manifest(make_study(tmp_path, good_sessions(1, ("v1",))))
    seen = []
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        run_study(study, tmp_path / "out", scheduler="tcp://127.0.0.1:9", pipeline=fake_pipeline,
                  progress=seen.append)  # fmt: skip
    assert not (tmp_path / "out").exists() and not seen
