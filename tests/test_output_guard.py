"""One guard for every path fabkit writes (fabkit.io.outputs): a shared template cannot make any
command write outside its output folder, and a failed write leaves nothing half-written.

Each test snapshots the whole temporary folder (the output folder, its parents and a folder
beside it) before and after the command, so a file that appears anywhere is caught.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from fabkit.cli import main
from fabkit.errors import OutputError, UnsafeNameError, WriteError
from fabkit.io.outputs import check_name, inside, output_folder, write_files

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
FOURBAR = (TEMPLATES / "fourbar.toml").read_text()
ORIGAMI = TEMPLATES / "origami_sheet.toml"

#: Names a hostile or careless template may carry; each must be refused at load.
EVIL_NAMES = {
    "parent": "../../escaped",
    "absolute": "/tmp/fabkit_escaped_absolute",
    "empty": "",
    "control": "a\u0001b",
    "separator": "a/b",
    "backslash": "..\\\\escaped",
    "hidden": ".hidden",
    "dash": "-rf",
    "reserved": "index.html",
    "device": "con",
    "long": "x" * 300,
}


def snapshot(folder: Path) -> dict:
    """Every file and link under ``folder`` with its size (folders by their entries)."""
    return {str(p.relative_to(folder)): (p.is_symlink(), p.lstat().st_size if p.is_file() else 0)
            for p in sorted(folder.rglob("*"))}


def evil_template(folder: Path, name: str, base: str = FOURBAR) -> Path:
    body = "\n".join(line for line in base.splitlines() if not line.startswith("name ="))
    text = f"name = {toml_string(name)}\n{body}\n"
    path = folder / "templates" / "evil.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def toml_string(s: str) -> str:
    return '"' + "".join(c if 32 <= ord(c) < 127 and c not in '"\\' else f"\\u{ord(c):04x}"
                         for c in s) + '"'


#: command → arguments after the template (each writes into -o unless told not to)
COMMANDS = {
    "simulate": ["simulate", "{t}", "-o", "{o}"],
    "map": ["map", "{t}", "-o", "{o}"],
    "tolerance": ["tolerance", "{t}", "-o", "{o}", "--samples", "5"],
    "export": ["export", "{t}", "-o", "{o}", "--tolerance-samples", "5"],
    "sweep": ["sweep", "{t}", "--vary", "nodes[3].x=0.9:1.1:2", "--measure", "fixed_points"],
    "fold": ["fold", "{t}", "-o", "{o}"],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", sorted(EVIL_NAMES))
def test_no_template_name_writes_outside_the_output_folder(command, case, tmp_path, monkeypatch,
                                                           capsys):
    base = ORIGAMI.read_text() if command == "fold" else FOURBAR
    template = evil_template(tmp_path, EVIL_NAMES[case], base)
    if command == "fold":  # the origami template names files beside it
        for ref in ORIGAMI.parent.glob("*.toml"):
            if ref.name != ORIGAMI.name:
                (template.parent / ref.name).write_text(ref.read_text())
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)  # sweep without -o writes under ./out
    out = tmp_path / "work" / "a" / "out"
    before = snapshot(tmp_path)
    argv = [a.format(t=template, o=out) for a in COMMANDS[command]]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fabkit: error: "), err
    assert "evil.toml: name: " in lines[0]
    assert snapshot(tmp_path) == before
    assert not Path("/tmp/fabkit_escaped_absolute").exists()


@pytest.mark.parametrize("command", ["simulate", "map", "tolerance", "export", "letters",
                                     "bench", "sweep", "fold"])
def test_an_empty_output_folder_is_refused(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    template = TEMPLATES / ("origami_sheet.toml" if command == "fold" else "fourbar.toml")
    argv = {"letters": ["letters", "NO", "-o", ""], "bench": ["bench", "--quick", "-o", ""],
            "sweep": ["sweep", str(template), "--vary", "nodes[3].x=0.9:1.1:2", "-o", ""]}.get(
        command, [command, str(template), "-o", ""])
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 1, err
    assert err.count("\n") == 1 and "-o: is empty" in err
    assert list(tmp_path.iterdir()) == []


def test_a_link_out_of_the_output_folder_is_not_written_through(tmp_path, capsys):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "fourbar").symlink_to(elsewhere)
    for argv in (["simulate", str(TEMPLATES / "fourbar.toml"), "-o", str(out)],
                 ["map", str(TEMPLATES / "fourbar.toml"), "-o", str(out)]):
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 1
        assert "is a symbolic link to" in err and "outside the output folder" in err
        assert list(elsewhere.iterdir()) == []


# --- the guard itself -------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(set(EVIL_NAMES.values())))
def test_check_name_refuses_every_unsafe_name(name):
    with pytest.raises(UnsafeNameError) as info:
        check_name(name)
    assert isinstance(info.value, ValueError)  # what Python users expect of a bad value
    assert len(str(info.value).splitlines()) == 1


@pytest.mark.parametrize("name", ["fourbar", "super_stable_chain", "a.b-c+d", "F00", "x" * 120])
def test_check_name_keeps_ordinary_names(name):
    assert check_name(name) == name


def test_inside_checks_every_part_of_a_relative_name(tmp_path):
    assert inside(tmp_path, "a", "chunks/x.json") == tmp_path / "a" / "chunks" / "x.json"
    for bad in ("chunks/../../x", "/etc/passwd", "a//b"):
        with pytest.raises(UnsafeNameError):
            inside(tmp_path, bad)


def test_output_folder_refuses_a_file_and_names_the_option(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(OutputError, match="--out: exists and is not a folder"):
        output_folder(f, "--out")
    with pytest.raises(OutputError, match="cannot be created: .* is not a folder"):
        output_folder(f / "below")
    assert output_folder(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"


def test_write_files_is_all_or_nothing(tmp_path, monkeypatch):
    (tmp_path / "b.txt").write_bytes(b"old")
    real = os.fsync
    calls = []

    def failing_fsync(fd):  # the third file meets a full disk
        calls.append(fd)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        real(fd)

    monkeypatch.setattr(os, "fsync", failing_fsync)
    with pytest.raises(WriteError) as info:
        write_files(tmp_path, {"a.txt": b"1", "b.txt": b"2", "c.txt": b"3"})
    assert info.value.path.endswith("c.txt")
    assert "No space left on device" in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.txt"]  # no temporary file left
    assert (tmp_path / "b.txt").read_bytes() == b"old"  # nothing replaced


# --- a real file-size limit: what the user sees when the disk fills --------------------------

def _limit_file_size():
    # writes past the limit fail with EFBIG instead of killing the process (SIGXFSZ ignored)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (30_000, 30_000))


@pytest.mark.parametrize("argv", [
    ["simulate", str(TEMPLATES / "fourbar.toml"), "--gif"],
    ["map", str(TEMPLATES / "chaotic.toml"), "--lyapunov", "--orbits", "20", "--average", "200",
     "--discard", "20"],
    ["letters", "NO"],
], ids=["simulate-gif", "map-lyapunov", "letters"])
def test_a_full_disk_leaves_nothing_and_names_the_file(argv, tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    proc = subprocess.run([sys.executable, "-m", "fabkit", *argv, "-o", str(out)],
                          capture_output=True, text=True, timeout=300, env=env,
                          preexec_fn=_limit_file_size)
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "cannot write: File too large; nothing of this output was written" in lines[0]
    assert lines[0].split(": ")[2].startswith(str(out))  # the file it could not write
    assert not out.exists()  # not even the folders it would have created


def test_a_full_disk_during_an_export_names_the_file_where_it_would_be(tmp_path):
    """The export writes into its staging folder: the line names the file in the design's
    folder (``out/fourbar/NAME``), not only its bare name beside the output folder."""
    import re

    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "fabkit", "export", "fourbar", "--to", "dxf",
                           "--tolerance-samples", "0", "--no-previews", "-q", "-o", str(out)],
                          capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"),
                          preexec_fn=_limit_file_size)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr
    named = re.search(r"File too large \((.+?)\); nothing of it was written", lines[0])
    assert named, lines[0]
    assert Path(named.group(1)).parent == out / "fourbar"
    assert not (out / "fourbar").exists()


def test_a_full_disk_under_the_lock_file_names_it(tmp_path, monkeypatch):
    from fabkit.io.outputs import LOCK_NAME, OutputLock

    real = os.write

    def full(fd, data):  # the lock's process id meets a full disk
        if os.path.basename(os.readlink(f"/proc/self/fd/{fd}")) == LOCK_NAME:
            raise OSError(28, "No space left on device")
        return real(fd, data)

    monkeypatch.setattr(os, "write", full)
    with pytest.raises(WriteError) as info:
        with OutputLock(tmp_path):
            pass
    assert info.value.path == str(tmp_path / LOCK_NAME)
    assert "No space left on device" in str(info.value)


def test_a_template_saved_onto_a_full_disk_names_the_file(tmp_path):
    target = tmp_path / "mine.toml"
    code = ("import resource, signal, fabkit\n"
            "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
            "design = fabkit.load_template('fourbar')\n"
            "resource.setrlimit(resource.RLIMIT_FSIZE, (100, 100))\n"
            "try:\n"
            f"    design.save({str(target)!r})\n"
            "except Exception as exc:\n"
            "    print(type(exc).__name__, exc)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.stdout.strip() == (f"WriteError {target}: cannot write: File too large; "
                                   "nothing of this output was written"), proc
    assert not target.exists()  # nothing half-written


# --- fabkit's own entries in an output folder: the lock, staging and backup folders ----------

EXPORT = ["export", "fourbar", "--to", "dxf", "--tolerance-samples", "0", "--no-previews", "-q"]


@pytest.mark.parametrize("case", ["link to a file outside", "dangling link", "fifo"])
def test_a_lock_file_that_is_no_file_of_ours_is_refused(case, tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    victim = outside / "victim"
    if case == "link to a file outside":
        victim.write_text("SECRET\n")
        (out / ".fabkit.lock").symlink_to(victim)
    elif case == "dangling link":
        (out / ".fabkit.lock").symlink_to(victim)
    else:
        os.mkfifo(out / ".fabkit.lock")
    before = snapshot(tmp_path)
    rc = main([*EXPORT, "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1, err
    assert f"{out / '.fabkit.lock'}: is a " in err[0]
    assert ("symbolic link" in err[0]) == (case != "fifo")
    assert ("FIFO" in err[0]) == (case == "fifo")
    assert snapshot(tmp_path) == before  # the target untouched, the link left in place
    if case == "link to a file outside":
        assert victim.read_text() == "SECRET\n"
    else:
        assert not victim.exists()


@pytest.mark.parametrize("entry", [".fourbar.old", ".fourbar.staging"])
def test_a_staging_or_backup_folder_that_is_a_link_is_refused(entry, tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    (outside / "mine.txt").write_text("not fabkit's\n")
    (out / entry).symlink_to(outside)
    before = snapshot(tmp_path)
    rc = main([*EXPORT, "-o", str(out)])
    cap = capsys.readouterr()
    assert rc == 1
    line = cap.err.strip()
    assert line == (f"fabkit: error: {out / entry}: is a symbolic link where fabkit keeps its "
                    "own folder; fabkit does not follow it: remove it"), cap.err
    assert snapshot(tmp_path) == before  # no out/fourbar, no hard link to the outside file
    assert not (out / "fourbar").exists()


def test_carrying_files_over_skips_special_files_and_keeps_links_as_links(tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    assert main([*EXPORT, "-o", str(out)]) == 0
    outside.mkdir()
    (outside / "target.txt").write_text("outside\n")
    folder = out / "fourbar"
    os.mkfifo(folder / "pipe")
    (folder / "link").symlink_to(outside / "target.txt")
    (folder / "notes.txt").write_text("mine\n")
    assert main([*EXPORT, "-o", str(out)]) == 0, capsys.readouterr().err
    assert (folder / "notes.txt").read_text() == "mine\n"
    assert (folder / "link").is_symlink()  # carried as the link, never its target's content
    assert not (folder / "pipe").exists()  # a FIFO is no command's output: not carried
    assert (outside / "target.txt").read_text() == "outside\n"
    assert sorted(p.name for p in outside.iterdir()) == ["target.txt"]


def test_sweep_chunks_never_go_through_a_link_out_of_the_folder(tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    (out / "chunks").symlink_to(outside)
    rc = main(["sweep", "chaotic", "--vary", "nodes[4].x=-0.4:-0.3:2", "--measure",
               "fixed_points", "--jobs", "1", "--no-plots", "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 1
    assert err == (f"fabkit: error: {out / 'chunks'}: is a symbolic link to {outside}, outside "
                   f"the output folder {out}; fabkit does not write through it")
    assert list(outside.iterdir()) == []


def test_bench_output_never_goes_through_a_link_and_is_refused_before_work(tmp_path, capsys):
    out, outside = tmp_path / "out", tmp_path / "outside"
    out.mkdir()
    outside.mkdir()
    (out / "bench").symlink_to(outside)
    rc = main(["bench", "--quick", "--sizes", "10", "--parts", "workprecision", "--budget", "1",
               "-o", str(out)])
    cap = capsys.readouterr()
    assert rc == 1
    assert "bench: is a symbolic link to" in cap.err and "outside the output folder" in cap.err
    assert cap.out == ""  # refused before the first measurement
    assert list(outside.iterdir()) == []


def test_open_own_file_refuses_links_and_fifos(tmp_path):
    from fabkit.io.outputs import open_own_file, own_entry

    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "nowhere")
    for name, words in (("fifo", r"is a FIFO \(named pipe\)"), ("link", "is a symbolic link")):
        with pytest.raises(OutputError, match=words):
            open_own_file(tmp_path / name)
    assert not (tmp_path / "nowhere").exists()
    fd = open_own_file(tmp_path / "lock")
    os.close(fd)
    assert (tmp_path / "lock").is_file()
    (tmp_path / ".d.old").symlink_to(tmp_path)
    with pytest.raises(OutputError, match="is a symbolic link where fabkit keeps its own folder"):
        own_entry(tmp_path, ".d.old")
    with pytest.raises(UnsafeNameError):
        own_entry(tmp_path, "../.d.old")
    assert own_entry(tmp_path, ".d.staging") == tmp_path / ".d.staging"
