"""Files that survive an interruption (issue 36): result files and table pairs are written whole or not at all,
folders are swapped whole, a file named by a file stays inside its folder, SIGTERM is handled like Ctrl-C."""
import os
import signal
from pathlib import Path

import pytest

from mrd_env import storage
from mrd_env.report import write_table


class _Interrupting:
    """A table cell whose formatting is interrupted (Ctrl-C while the table is being written)."""

    def __str__(self):
        raise KeyboardInterrupt

    __format__ = __repr__ = lambda self, *a: str(self)  # noqa: E731


def test_an_interrupted_table_leaves_both_files_of_the_pair_as_they_were(tmp_path):
    md, csv = write_table([{"a": float(i)} for i in range(50)], tmp_path / "t")
    before = md.read_text(), csv.read_text()
    rows = [{"a": float(i)} for i in range(20)] + [{"a": _Interrupting()}]
    with pytest.raises(KeyboardInterrupt):
        write_table(rows, tmp_path / "t")
    assert (md.read_text(), csv.read_text()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv", "t.md"]  # no temporary file left behind


def test_a_table_pair_is_written_with_the_same_rows(tmp_path):
    md, csv = write_table([{"a": 1.5, "b": "x,y"}, {"a": 2.0, "b": "z"}], tmp_path / "sub" / "t")
    assert csv.read_bytes() == b'a,b\r\n1.5,"x,y"\r\n2.0,z\r\n'   # csv's own line ends, as before
    assert md.read_text().splitlines()[-2:] == ["| 1.5 | x,y |", "| 2 | z |"]


def test_an_atomic_write_never_follows_a_planted_symlink(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "out.json").symlink_to(victim)
    storage.write_json(tmp_path / "out.json", {"a": 1})
    assert victim.read_text() == "precious"
    assert not (tmp_path / "out.json").is_symlink() and (tmp_path / "out.json").read_text() == '{"a": 1}'


def test_a_folder_is_swapped_whole(tmp_path):
    target = tmp_path / "agent"
    target.mkdir()
    (target / "a").write_text("old")
    (target / "stale").write_text("old only")
    staged = storage.staging_folder(target)
    (staged / "a").write_text("new")
    storage.replace_folder(staged, target)
    assert sorted(p.name for p in target.iterdir()) == ["a"] and (target / "a").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["agent"]   # the staging folder and the old content are gone


def test_a_folder_moved_aside_by_a_killed_swap_is_put_back(tmp_path):
    target = tmp_path / "agent"
    aside = tmp_path / ("agent" + storage.ASIDE)
    aside.mkdir()
    (aside / "a").write_text("previous")
    assert (storage.recover_folder(target) / "a").read_text() == "previous"


@pytest.mark.parametrize("name", ["/etc/passwd", "../x.npz", "a/../../x.npz", "", 3])
def test_a_named_file_outside_its_folder_is_refused(tmp_path, name):
    with pytest.raises(ValueError, match="model"):
        storage.inside(tmp_path, name, what="model")


def test_a_symlink_leaving_the_folder_is_refused(tmp_path):
    folder = tmp_path / "agent"
    folder.mkdir()
    (tmp_path / "elsewhere.npz").write_bytes(b"x")
    (folder / "model.npz").symlink_to(tmp_path / "elsewhere.npz")
    with pytest.raises(ValueError, match="leaves the folder"):
        storage.inside(folder, "model.npz", what="model")
    (folder / "real.npz").write_bytes(b"x")
    assert storage.inside(folder, "real.npz") == folder.resolve() / "real.npz"


def test_sigterm_ends_a_command_like_ctrl_c_with_exit_143(monkeypatch, capsys):
    import experiments.commands.benchmark as cmd
    from experiments.cli import main

    seen = []

    def run(args):
        import gc

        # no garbage collection while the signal is pending: its handler would otherwise run inside a gc callback
        # (hypothesis installs one) and its KeyboardInterrupt be "ignored" there, an alarming traceback at the end
        # of the test run and a test that does not see the interrupt
        gc.disable()
        try:
            os.kill(os.getpid(), signal.SIGTERM)
        except KeyboardInterrupt:   # what a long command's save-on-interrupt sees
            seen.append("saved")
            raise
        finally:
            gc.enable()
        return 0

    monkeypatch.setattr(cmd, "run", run)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["benchmark"]) == 143
    assert seen == ["saved"]
    assert capsys.readouterr().err == "mrd-env benchmark: terminated\n"
    assert signal.getsignal(signal.SIGTERM) == before   # the caller's handler is restored


@pytest.mark.hostile
def test_read_limited_refuses_devices_fifos_and_big_files(tmp_path):
    """A shared file is read only if it is a regular file within its size cap: /dev/zero, a FIFO (which a plain open
    waits on forever) and a file over the cap are refused by name, without reading them."""
    import os

    from mrd_env.storage import read_limited

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    big = tmp_path / "big.json"
    big.write_bytes(b"x" * 101)
    link = tmp_path / "link.json"
    link.symlink_to("/dev/zero")
    for path, why in ((Path("/dev/zero"), "not a regular file"), (fifo, "not a regular file"),
                      (link, "not a regular file"), (big, "101 bytes, more than the 100"),
                      (tmp_path / "missing", "cannot be read")):
        with pytest.raises(ValueError, match=why) as err:
            read_limited(path, 100, what="suite file")
        assert str(err.value).startswith(f"suite file {path}")
    ok = tmp_path / "ok.json"
    ok.write_bytes(b"x" * 100)
    assert read_limited(ok, 100) == b"x" * 100


def test_written_files_follow_the_umask(tmp_path):
    """Results, tables and agent folders are written with the modes a plain open or mkdir would give (0666/0777 less
    the umask), not mkstemp's 0600: a teaching assistant reads the students' outputs in a shared folder."""
    import stat

    old = os.umask(0o022)
    try:
        a = storage.write_text(tmp_path / "a.json", "{}")
        b, c = storage.write_texts({tmp_path / "b.md": "x", tmp_path / "b.csv": "y"})
        with storage.atomic_path(tmp_path / "d.npz") as tmp:
            tmp.write_bytes(b"z")
        staged = storage.staging_folder(tmp_path / "agent")
        for f in (a, b, c, tmp_path / "d.npz"):
            assert stat.S_IMODE(f.stat().st_mode) == 0o644, f
        assert stat.S_IMODE(staged.stat().st_mode) == 0o755
        os.umask(0o077)
        assert stat.S_IMODE(storage.write_text(tmp_path / "e.json", "{}").stat().st_mode) == 0o600
    finally:
        os.umask(old)
