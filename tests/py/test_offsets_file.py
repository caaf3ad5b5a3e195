"""The offsets file as a hostile local user, a careless operator and a power
cut meet it (issue 17, items 1, 2, 3, 7 and the low items): through the
tools that read and write it (mlip-sim --offsets/--save-offsets, mlip-feed
--offsets with a real mlip-rt --can none, mlip-offsets). The write never
goes through a link another user planted and keeps the file's mode; a file
cut short, empty, NUL-filled, a directory, a number cut short, a key twice,
a missing file: refused before anything runs; a value entered during a run
survives the write-back; values land on their axis by letter."""
import os
import re
import shutil
import signal
import subprocess
import tempfile

import pytest

from conftest import CONFIG, Proc, offsets_file, run, status, tool, wait_for

MILL = CONFIG / "mill-3axis.ini"
ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="needs root (another user)")
NOBODY = ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups"]


def sim(prog, off, *extra, **kw):
    return run(["mlip-sim", "-q", "--config", MILL, "--offsets", off, *extra, prog],
               check=False, **kw)


def program(tmp_path, text="G55 G1 X1 Y1 F600\nG10 L2 P1 X5\nG54 G1 X0 Y0\n"):
    p = tmp_path / "p.ngc"
    p.write_text(text)
    return p


# ---- item 1: the write, as another user would attack it ---------------------

@pytest.fixture
def nobodys_folder():
    """A folder that user nobody owns (and so can plant links in)."""
    d = tempfile.mkdtemp(prefix="mlip-offsets-", dir="/tmp")
    os.chown(d, 65534, 65534)
    yield d
    shutil.rmtree(d, ignore_errors=True)


@ROOT_ONLY
def test_a_planted_link_is_never_written_through(tmp_path, nobodys_folder):
    """Observed on main: the save opened FILE.tmp with O_CREAT|O_TRUNC and
    no O_EXCL/O_NOFOLLOW: nobody links FILE.tmp to a root-only file, root's
    `mlip-sim --save-offsets` wrote the offsets into it and FILE became
    nobody's link. Now: a new file of a random name, created exclusively;
    the root file untouched, FILE a regular file, its mode 0600 kept."""
    secret = tmp_path / "secret"
    secret.write_text("root only\n")
    secret.chmod(0o600)
    off = os.path.join(nobodys_folder, "offsets")
    offsets_file(off, "G55 X10 Y20 Z0")
    os.chmod(off, 0o600)
    subprocess.run(NOBODY + ["ln", "-s", str(secret), off + ".tmp"], check=True)
    p = subprocess.run([tool("mlip-sim"), "-q", "--config", str(MILL), "--offsets", off,
                        "--save-offsets", str(program(tmp_path))], capture_output=True,
                       text=True, preexec_fn=lambda: os.umask(0))
    assert secret.read_text() == "root only\n" and secret.stat().st_mode & 0o777 == 0o600
    assert p.returncode == 0, p.stderr
    st = os.lstat(off)
    assert os.path.isfile(off) and not os.path.islink(off)
    assert st.st_mode & 0o777 == 0o600 and st.st_uid == 0  # kept, not 0666 under umask 0
    assert "\nG54 X5 Y0 Z0\n" in open(off).read()  # the program's G10 is in
    assert os.path.islink(off + ".tmp")  # left as it was: never used
    # FILE itself replaced by nobody's link to the root file: refused both
    # ways, the root file untouched
    subprocess.run(NOBODY + ["sh", "-c", f"rm -f {off} && ln -s {secret} {off}"], check=True)
    p = sim(program(tmp_path), off, "--save-offsets")
    assert p.returncode == 1 and f"{off} is a symbolic link" in p.stderr, p.stderr
    assert secret.read_text() == "root only\n"


@ROOT_ONLY
def test_mlip_feed_write_back_ignores_a_planted_link(tmp_path, nobodys_folder, controller):
    """The same through a completed mlip-feed --offsets (its write-back)."""
    shm, _ = controller()
    secret = tmp_path / "secret"
    secret.write_text("root only\n")
    secret.chmod(0o600)
    off = os.path.join(nobodys_folder, "offsets")
    offsets_file(off)
    subprocess.run(NOBODY + ["ln", "-s", str(secret), off + ".tmp"], check=True)
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", "--offsets", off,
                        str(program(tmp_path, "G1 X1 F6000\nG10 L2 P2 X7\n"))],
                       capture_output=True, text=True, timeout=60)
    assert secret.read_text() == "root only\n"
    assert p.returncode == 0, p.stderr
    assert "\nG55 X7 Y0 Z0\n" in open(off).read() and not os.path.islink(off)


def test_mode_kept_and_umask_respected(tmp_path):
    """A 0600 file stays 0600 (main: 0644, or 0666 under umask 0); a new
    file gets 0666 less the umask."""
    off = tmp_path / "offsets"
    subprocess.run([tool("mlip-offsets"), "--init", "--config", str(MILL), str(off)],
                   check=True, capture_output=True, preexec_fn=lambda: os.umask(0o077))
    assert off.stat().st_mode & 0o777 == 0o600
    off.chmod(0o640)
    for mask in (0, 0o022):
        p = subprocess.run([tool("mlip-sim"), "-q", "--config", str(MILL), "--offsets",
                            str(off), "--save-offsets", str(program(tmp_path))],
                           capture_output=True, text=True, preexec_fn=lambda: os.umask(mask))
        assert p.returncode == 0, p.stderr
        assert off.stat().st_mode & 0o777 == 0o640
    assert [f.name for f in tmp_path.iterdir() if ".tmp" in f.name] == []  # none left


# ---- item 2: a damaged file is refused, never zeros --------------------------

def damaged(tmp_path, kind):
    off = offsets_file(tmp_path / "offsets", "SELECT G55", "G55 X-20 Y20 Z0")
    text = off.read_bytes()
    if kind == "cut before G55":
        off.write_bytes(text[:text.index(b"\nG55 ") + 1])
    elif kind == "empty":
        off.write_bytes(b"")
    elif kind == "NUL-filled":
        off.write_bytes(b"\0" * len(text))
    elif kind == "directory":
        off.unlink()
        off.mkdir()
    elif kind == "number cut short":
        off.write_bytes(text[:text.index(b"\nG55 X-20") + len(b"\nG55 X-2")])
    return off


@pytest.mark.parametrize("kind,says", [
    ("cut before G55", "no end marker ('# end N lines sha256 ...' as the last line): the "
                       "file was cut short"),
    ("empty", "is empty: a write cut short"),
    ("NUL-filled", ":1: a NUL byte (offset 0): what a power cut leaves"),
    ("directory", "is a directory, not a regular file"),
    ("number cut short", "cut short (no end of line)"),
])
def test_damaged_file_is_refused(tmp_path, kind, says):
    """Observed on main: each loaded as G54 X0 Y0 Z0 (a number cut short as
    -2), exit 0: a wrong work offset drives a tool into the part. Now the
    program does not run (no trace), and the message says what to do."""
    off = damaged(tmp_path, kind)
    trace = tmp_path / "t.csv"
    p = sim(program(tmp_path), off, "--trace", trace)
    assert p.returncode == 1, p.stderr
    assert says in p.stderr and not trace.exists(), p.stderr
    if kind != "directory":
        assert "measure the offsets again and enter them" in p.stderr, p.stderr


def test_save_syncs_file_and_folder(tmp_path):
    """fsync of the new file before the rename, then of the folder (strace
    shows the calls, in that order)."""
    if shutil.which("strace") is None:
        pytest.fail("strace missing: tools/deps.sh installs it")
    off = offsets_file(tmp_path / "offsets")
    # a sanitizer build (make sanitize, asan): LeakSanitizer cannot run under
    # ptrace and would fail the tool at exit; the leak check is not this test's
    asan = ":".join(o for o in (os.environ.get("ASAN_OPTIONS", ""), "detect_leaks=0") if o)
    p = subprocess.run(["strace", "-f", "-e", "trace=openat,fsync,renameat,renameat2,rename",
                        tool("mlip-offsets"), "--set", "G55 X1", str(off)],
                       capture_output=True, text=True, env={**os.environ, "ASAN_OPTIONS": asan})
    assert p.returncode == 0, p.stderr
    calls = [l for l in p.stderr.splitlines() if re.search(r"(fsync|rename|O_EXCL)", l)]
    kinds = [("create" if "O_EXCL" in l else "fsync" if "fsync" in l else "rename")
             for l in calls]
    assert kinds == ["create", "fsync", "rename", "fsync"], calls
    assert "O_NOFOLLOW" in calls[0] and "O_CLOEXEC" in calls[0]


# ---- item 3: a change during the run survives -------------------------------

def test_offsets_entered_during_a_run_survive(tmp_path, controller):
    """Observed on main: the write-back rewrote the whole file from the copy
    read at the start: a G56 entered for the next fixture while the program
    ran was gone. The program here sets G55 (G10 L2 P2) and pauses (M0);
    meanwhile the operator enters G56; after the run the file has both.
    Then both change G55: refused, the operator's value kept, the
    program's shown."""
    shm, _ = controller()
    off = offsets_file(tmp_path / "offsets")

    def run_with_edit(g55_x, edit):
        prog = program(tmp_path, f"G10 L2 P2 X{g55_x}\nG1 X10 F6000\nM0\nG1 X20\nM2\n")
        f = Proc([tool("mlip-feed"), "--shm", shm, "--offsets", str(off),
                  str(prog)], stderr=subprocess.PIPE, text=True)
        assert wait_for(lambda: (status(shm) or {}).get("state") == "paused", 30)
        run(["mlip-offsets", "--set", edit, off])
        assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "resume"],
                              capture_output=True).returncode == 0
        err = f.communicate(timeout=60)[1]
        return f.returncode, err

    rc, err = run_with_edit(5, "G56 X7 Y8 Z9")
    assert rc == 0, err
    text = off.read_text()
    assert "\nG55 X5 Y0 Z0\n" in text and "\nG56 X7 Y8 Z9\n" in text, text
    assert "merged with a change made during the program: G56 kept" in err, err
    rc, err = run_with_edit(4, "G55 X6")  # the program sets X4, the operator X6
    assert rc == 1, err
    assert "G55 changed both there and by the program: nothing was written" in err, err
    assert "mlip-feed:   G55 X4 Y0 Z0" in err  # what the program left, shown
    assert "\nG55 X6 Y0 Z0\n" in off.read_text()


# ---- item 7: axis letters -----------------------------------------------------

def test_values_land_on_their_axis_by_letter(tmp_path):
    """Observed on main: values in config order, no letters: with
    COORDINATES = X Z Y the same file put the Z offset (70 mm) on Y."""
    off = offsets_file(tmp_path / "offsets", "SELECT G55", "G55 X0 Y0 Z-70")
    xzy = tmp_path / "xzy.ini"
    xzy.write_text(re.sub(r"(?m)^COORDINATES = X Y Z", "COORDINATES = X Z Y",
                          MILL.read_text()))
    prog = program(tmp_path, "G0 X0 Y0 Z10\n")
    trace = tmp_path / "t.csv"
    p = run(["mlip-sim", "-q", "--config", xzy, "--offsets", off, "--trace", trace, prog],
            check=False)
    assert p.returncode == 0, p.stderr
    head, *rows = trace.read_text().splitlines()
    cols = head.split(",")
    last = dict(zip(cols, map(float, rows[-1].split(","))))
    z = next(c for c in cols if c.upper().startswith("Z"))
    y = next(c for c in cols if c.upper().startswith("Y"))
    assert last[z] == -60.0 and last[y] == 0.0, (head, rows[-1])


# ---- the low items ------------------------------------------------------------

def test_misspelled_path_is_an_error(tmp_path):
    """Observed on main: a misspelled --offsets path gave the defaults."""
    offsets_file(tmp_path / "offsets", "G55 X10")
    p = sim(program(tmp_path), tmp_path / "ofsets")
    assert p.returncode == 1
    assert f"{tmp_path / 'ofsets'}: no such offsets file: check the path" in p.stderr
    assert "mlip-offsets --init --config CONFIG" in p.stderr


def test_duplicated_key_is_an_error(tmp_path):
    """Observed on main: a duplicated key took the last value. Now refused,
    both lines named; mlip-offsets --accept refuses it too."""
    off = offsets_file(tmp_path / "offsets")
    text = off.read_text().replace("\nG55 X0 Y0 Z0\n", "\nG55 X0 Y0 Z0\nG55 X9 Y0 Z0\n")
    off.write_text(text)
    p = run(["mlip-offsets", "--accept", off], check=False)
    first = text[:text.index("\nG55 ")].count("\n") + 2
    assert p.returncode == 1
    assert f"{off}:{first + 1}: G55 a second time (first on line {first})" in p.stderr


def test_old_format_is_refused_with_its_conversion(tmp_path):
    """A file of the old format (KEY = values in config order, no marker)
    cannot be told from one cut short: refused with the command that
    converts it; converted, it runs with the same values."""
    off = tmp_path / "offsets"
    off.write_text("SELECT = G55\nG92_ON = 0\nG55 = 10 20 -5\n")
    p = sim(program(tmp_path), off)
    assert p.returncode == 1 and "the old format" in p.stderr
    assert f"mlip-offsets --convert --config CONFIG {off}" in p.stderr
    c = run(["mlip-offsets", "--convert", "--config", MILL, off])
    assert "G55     X10 Y20 Z-5" in c.stdout and "axis order XYZ" in c.stdout
    p = sim(program(tmp_path), off)
    assert p.returncode == 0, p.stderr


def test_mlip_offsets_tool(tmp_path):
    """show, --set (axes not named keep theirs), --init refuses an existing
    file, a value that is no number, an unknown key."""
    off = offsets_file(tmp_path / "offsets", "G55 X10 Y20 Z-5")
    assert "G55     X10 Y20 Z-5" in run(["mlip-offsets", off]).stdout
    assert "G55     X10 Y20 Z1.5" in run(["mlip-offsets", "--set", "G55 z1.5", off]).stdout
    p = run(["mlip-offsets", "--init", "--config", MILL, off], check=False)
    assert p.returncode == 1 and "exists: it is left as it is" in p.stderr
    p = run(["mlip-offsets", "--set", "G55 X1.2.3", off], check=False)
    assert p.returncode == 1 and "G55: X '1.2.3' is not a number" in p.stderr
    p = run(["mlip-offsets", "--set", "G53 X1", off], check=False)
    assert p.returncode == 1 and "unknown key 'G53'" in p.stderr
    assert "G55     X10 Y20 Z1.5" in run(["mlip-offsets", off]).stdout  # unchanged
