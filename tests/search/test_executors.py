"""Dask distributed: the same seed gives the same ranking as the local run (in-process
scheduler with worker processes), an unreachable scheduler is one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the [distributed] extra is not installed")

from sensorgap.cli import main  # noqa: E402
from sensorgap.errors import InputError  # noqa: E402
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


def test_a_silent_peer_or_a_scheduler_without_workers_is_one_line() -> None:
    """Hostile round 29: a server that accepts and never answers hung the search for ever
    (Dask bounds the connection, not the handshake after it), bytes that are no Dask
    message were an internal error (``struct.error``), and a real scheduler with no
    workers waited for ever. ``_remote_client`` bounds the connection by 2 x its timeout
    and says each in one line naming the scheduler (here with stand-ins for Dask's
    client: a real hung handshake leaves its thread behind, reproduced by hand with a
    silent server, hostile round 29's F1)."""
    import struct
    import threading

    from sensorgap.search.executors import _remote_client

    class Silent:
        def __init__(self, address: str, timeout: float) -> None:
            threading.Event().wait(30.0)  # a handshake that never comes (until 30 s)

    class Garbage:
        def __init__(self, address: str, timeout: float) -> None:
            struct.unpack("<Q", b"\x00")

    class Idle:
        closed = False

        def __init__(self, address: str, timeout: float) -> None:
            pass

        def scheduler_info(self) -> dict[str, dict[str, object]]:
            return {"workers": {}}

        def close(self) -> None:
            Idle.closed = True

    with pytest.raises(
        InputError,
        match=r"^scheduler: 'tcp://h:1' did not answer as a Dask "
        r"scheduler within 0\.2 s \(it accepted the connection",
    ):
        _remote_client(Silent, "tcp://h:1", 0.1)
    with pytest.raises(InputError, match=r"did not answer as a Dask scheduler \(struct\.error\)"):
        _remote_client(Garbage, "tcp://h:1", 1.0)
    with pytest.raises(
        InputError, match=r"^scheduler: the Dask scheduler 'tcp://h:1' has no workers"
    ):
        _remote_client(Idle, "tcp://h:1", 1.0)
    assert Idle.closed
