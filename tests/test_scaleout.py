"""``scaleout.scheduler_client``: the local process cluster it starts for a job."""

import contextlib
import socket
import warnings

import pytest

from voxfield.scaleout import scheduler_client

DASK_DEFAULT_HTTP_PORT = 8787


def test_a_process_cluster_leaves_dasks_default_port_to_others():
    """Two jobs at once, or a job beside a user's own cluster, must not fight over 8787: with
    the port held, starting the job's cluster warns of nothing and its scheduler serves
    elsewhere, on the loopback interface."""
    pytest.importorskip("distributed")
    with socket.socket() as held, warnings.catch_warnings(record=True) as caught:
        with contextlib.suppress(OSError):  # already held by someone else: as good
            held.bind(("127.0.0.1", DASK_DEFAULT_HTTP_PORT))
            held.listen()
        warnings.simplefilter("always")
        with scheduler_client("processes") as client:
            scheduler = client.cluster.scheduler
            http_host, http_port = scheduler.http_server.address, scheduler.http_server.port
            assert client.submit(sum, [1, 2, 3]).result() == 6
    assert http_port != DASK_DEFAULT_HTTP_PORT
    assert http_host == "127.0.0.1"
    assert not [w for w in caught if str(DASK_DEFAULT_HTTP_PORT) in str(w.message)]
