"""The grid of trainings on a Dask cluster (danae_lite.danae.networks.use_scheduler): a
distributed.LocalCluster on the loopback address, two worker processes with one thread each,
gives the cross-validation rows of a run on this machine with one thread, exactly."""
import pandas as pd
import pytest

from danae_lite.danae import networks
from danae_lite.data import simulate
from danae_lite.danae.train_types import TrainConfig
from danae_lite.research import crossval

from conftest import network_items

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def splits():
    recs = [simulate.simulate("handheld", duration=8.0, seed=s, name=f"h{s}") for s in range(3)]
    return crossval.leave_one_out(recs, "handheld")


def _run(splits, **kw):
    return crossval.run_splits(splits, name="oxiod", data="simulated", methods=("paper_kf", "danae"), seeds=(0, 1),
                               train_config=TrainConfig(max_steps=3, num_threads=1), progress=False, **kw)


@pytest.fixture
def scheduler():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        networks.use_scheduler(cluster.scheduler_address)
        try:
            yield cluster.scheduler_address
        finally:
            networks.use_scheduler(None)
            networks._dask_client(cluster.scheduler_address).close()
            networks._dask_client.cache_clear()


def test_the_cluster_trains_the_networks_and_the_rows_are_those_of_this_machine(splits, scheduler, tmp_path):
    local = _run(splits)                                  # one process, no cache, one torch thread
    client = networks._dask_client(scheduler)
    with distributed.get_task_stream(client=client) as stream:
        clustered = _run(splits, cache=tmp_path, jobs=2)  # networks on the cluster, splits here
    # 3 splits x 3 angles x 2 seeds, stored by this process as they came back
    assert len(network_items(tmp_path)) == 18
    assert stream.data, "no task ran on the cluster"
    workers = {task["worker"] for task in stream.data}
    assert workers <= set(client.scheduler_info()["workers"])
    pd.testing.assert_frame_equal(clustered.rows, local.rows)


def test_a_scheduler_address_is_checked_where_it_is_given():
    from danae_lite import runtime

    assert runtime.scheduler("tcp://127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    assert runtime.scheduler("") is None
    for bad in ("127.0.0.1", "tcp://host", "tcp://host:port"):
        with pytest.raises(ValueError, match="Dask scheduler address"):
            runtime.scheduler(bad)


def test_dask_is_imported_only_when_a_scheduler_is_named():
    import subprocess
    import sys

    probe = ("import sys; import danae_lite.danae.networks, danae_lite.research.crossval, danae_lite.cli; "
             "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    assert subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout == "[]\n"
