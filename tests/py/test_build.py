"""The build's own guarantees: every README command installs what it needs
first, and the layering checks (make purity) catch what they are there for."""
import shutil
import subprocess

import pytest

from conftest import BUILD, ROOT


@pytest.mark.parametrize("target", ["demo", "run", "bench", "test"])
def test_readme_commands_install_their_deps_first(target):
    """Observed on main: `make demo` on a fresh machine failed at once
    (libsocketcan.h: No such file): unlike make test it did not install what
    it needs. Each of them now runs tools/deps.sh before anything is built.
    (make -n runs only the recursive make lines, which print theirs.)"""
    p = subprocess.run(["make", "-n", "--no-print-directory", f"BUILD={BUILD}", target],
                       cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    lines = [l for l in p.stdout.splitlines() if l.strip()]
    assert lines and lines[0].strip() == "tools/deps.sh", lines[:3]


def test_purity_refuses_an_impure_core(tmp_path):
    """tools/purity.sh passes on the real libmlip.a and names the symbol and
    object when a member of the archive calls printf or malloc."""
    ok = subprocess.run([ROOT / "tools" / "purity.sh", BUILD / "libmlip.a"], capture_output=True,
                        text=True)
    assert ok.returncode == 0, ok.stderr
    src = tmp_path / "impure.c"
    src.write_text("#include <stdio.h>\n#include <stdlib.h>\n"
                   "void mlip_impure(void);\n"
                   "void mlip_impure(void) { printf(\"x\"); free(malloc(3)); }\n")
    obj = tmp_path / "impure.o"
    subprocess.run(["cc", "-c", src, "-o", obj], check=True)
    lib = tmp_path / "libmlip.a"
    shutil.copy(BUILD / "libmlip.a", lib)
    subprocess.run(["ar", "rs", lib, obj], check=True, capture_output=True)
    bad = subprocess.run([ROOT / "tools" / "purity.sh", lib], capture_output=True, text=True)
    assert bad.returncode == 1
    for sym in ("malloc", "free"):
        assert f"  {sym}  (in impure.o )" in bad.stderr, bad.stderr


def test_src_sees_include_only(tmp_path):
    """src/ compiles against include/ only: a core file that included rt.h
    or a tools/lib header would not build (the Makefile gives src/ -Iinclude
    alone)."""
    p = subprocess.run(["make", "-n", "--no-print-directory", "-B", f"BUILD={tmp_path}",
                        f"{tmp_path}/obj/src/planner.o"], cwd=ROOT, capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    cc = [l for l in p.stdout.splitlines() if "src/planner.c" in l]
    assert cc and "-Iinclude" in cc[0] and "-Irt" not in cc[0] and "-Itools/lib" not in cc[0]
