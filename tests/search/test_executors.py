"""Dask distributed: the same seed gives the same ranking as the local run (in-process
scheduler with worker processes), an unreachable scheduler is one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the [distributed] extra is not installed")

from sensorgap.cli import main  # noqa: E402
from sensorgap.search.executors import DaskExecutor  # noqa: E402
from sensorgap.search.run import run_search  # noqa: E402

KW = {
    "vehicle": "system_b",
    "families": ["cut_in_left", "crossing_pedestrian"],
    "environments": ["clear", "glare_front_right"],
    "budget": 600,
    "seed": 3,
    "top": 6,
    "strategy": "de",
}


@pytest.mark.slow
def test_dask_gives_the_local_ranking(tmp_path: Path) -> None:
    run_search(out=tmp_path / "local", **KW)  # type: ignore[arg-type]
    run_search(
        out=tmp_path / "dask",
        executor="dask",
        workers=2,  # type: ignore[arg-type]
        **KW,
    )
    for name in ("ranking.csv", "ranking.json"):
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "dask" / name).read_bytes()


def test_unreachable_scheduler_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Dask retries a refused connection until the executor's timeout (10 s by default):
    # 1 s here gives the same refusal without the suite waiting 9 s for it
    init = DaskExecutor.__init__

    def quick_init(
        self: DaskExecutor, address: str | None = None, workers: int = 2, timeout_s: float = 1.0
    ) -> None:
        init(self, address, workers, timeout_s=1.0)

    monkeypatch.setattr(DaskExecutor, "__init__", quick_init)
    code = main(
        [
            "search",
            "--vehicle",
            "system_b",
            "--families",
            "crossing_pedestrian",
            "--environments",
            "clear",
            "--budget",
            "10",
            "--executor",
            "dask",
            "--scheduler",
            "tcp://127.0.0.1:9",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and "cannot reach the Dask scheduler" in err
    assert len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()  # no empty folder left behind (review round four)


def test_a_second_local_cluster_warns_of_no_busy_port() -> None:
    """A local cluster while another one holds Dask's HTTP port 8787 (two searches at
    once): the scheduler's HTTP server (no dashboard) takes a free local port without a
    word (found while a hostile round ran a Dask search beside the suite: "UserWarning:
    Port 8787 is already in use" on stderr)."""
    import socket
    import warnings

    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen()
    except OSError:
        pass  # held by someone else: busy all the same
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            ex = DaskExecutor(workers=1)
            ex.close()
    finally:
        holder.close()
    assert [str(w.message) for w in seen if "Port" in str(w.message)] == []


def test_an_address_where_no_scheduler_answers_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 28, F3: a --scheduler address where something else answers (bytes
    that Dask decodes as a frame of EiB): it was "out of memory" and left an empty
    search.sqlite. Now one line naming --scheduler, exit 2, no --out folder."""
    import contextlib
    import socket
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    port = server.getsockname()[1]

    def answer() -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with contextlib.suppress(OSError):
                conn.sendall(b"HTTP/1.0 200 OK\r\n\r\n" + b"\xff" * 100_000)
            conn.close()

    threading.Thread(target=answer, daemon=True).start()
    out = tmp_path / "out"
    argv = ["search", "--vehicle", "system_b", "--families", "cut_out_reveal"]
    argv += ["--environments", "fog_50", "--budget", "10", "--executor", "dask"]
    try:
        code = main([*argv, "--scheduler", f"tcp://127.0.0.1:{port}", "--out", str(out)])
    finally:
        server.close()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert f"--scheduler: 'tcp://127.0.0.1:{port}' did not answer as a Dask scheduler" in err
    assert not out.exists()


def test_a_silent_peer_or_a_scheduler_without_workers_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 29: a server that accepts and never answers hung the search for ever
    (Dask bounds the connection, not the handshake after it), and so did a real scheduler
    with no workers. Both are now one line naming --scheduler, exit 2, no --out folder."""
    import socket

    from distributed import LocalCluster

    from sensorgap.search import executors

    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen()
    argv = ["search", "--vehicle", "system_b", "--families", "cut_out_reveal"]
    argv += ["--environments", "fog_50", "--budget", "10", "--executor", "dask"]
    address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
    init = executors.DaskExecutor.__init__

    def quick(self: executors.DaskExecutor, a: str | None = None, workers: int = 2) -> None:
        init(self, a, workers, timeout_s=1.0)  # 2 s for the handshake, not 20

    executors.DaskExecutor.__init__ = quick  # type: ignore[method-assign]
    try:
        code = main([*argv, "--scheduler", address, "--out", str(tmp_path / "a")])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert f"--scheduler: '{address}' did not answer as a Dask scheduler within 2 s" in err
    finally:
        executors.DaskExecutor.__init__ = init  # type: ignore[method-assign]
        silent.close()
    assert not (tmp_path / "a").exists()
    with LocalCluster(
        n_workers=0, processes=False, protocol="tcp", host="127.0.0.1", dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        code = main([*argv, "--scheduler", address, "--out", str(tmp_path / "b")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert f"--scheduler: the Dask scheduler '{address}' has no workers" in err
    assert not (tmp_path / "b").exists()
