#!/usr/bin/env python3
"""Mutation check of the validation rules: each rule removed or weakened in
turn in a scratch copy of the tree, rebuilt, and the tests that guard it run;
every mutant must make one of them fail (issue 22: a validation rule no test
can see fail is no rule).

    tools/mutate.py [--only NAME] [--list] [--keep DIR]

The mutants cover the controller's record validation (the rule set of
every block, mlip_block_check in include/mlip/types.h, and the record's own
fields in src/ctl/controller.c), what the G-code reader keeps of that rule set
and of LinuxCNC's rules, the machine's ranges, mlip-rt's fault log and the
checker's order test. Prints a table: mutant, the first listed test that
failed (the one that kills it), or SURVIVED. Exit 0: every mutant killed;
1: one survived; 2: setup (a mutant's text no longer in its file, a build).

Run by hand or in CI when time allows (`make mutate`; about a quarter of an
hour on two cores: one build, then per mutant a rebuild of what its tests
need and those tests).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Mutant:
    name: str
    path: str  # file in the tree
    old: str  # text that must occur exactly once
    new: str
    tests: tuple[str, ...]  # "unit:BINARY" or "py:NODEID", in the order tried


UNIT_CTL = "unit:test_controller"
UNIT_GC = "unit:test_gcode"
UNIT_CFG = "unit:test_config"
TYPES = "include/mlip/types.h"
CTL = "src/ctl/controller.c"

MUTANTS: tuple[Mutant, ...] = (
    # -- the record's own fields (controller.c)
    Mutant(
        "record: sequence not checked",
        CTL,
        "if (expect_seq != 0 && rec->seq != expect_seq) {",
        "if (0 && expect_seq != 0 && rec->seq != expect_seq) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: type not checked",
        CTL,
        "if (rec->type >= MLIP_REC_TYPES) {",
        "if (0 && rec->type >= MLIP_REC_TYPES) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: flags not checked",
        CTL,
        "if ((rec->flags & ~MLIP_REC_FLAGS) != 0) {",
        "if (0 && (rec->flags & ~MLIP_REC_FLAGS) != 0) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: a broken tolerance rule ignored",
        CTL,
        "if (rule == MLIP_RULE_TOL) {",
        "if (0 && rule == MLIP_RULE_TOL) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: a broken feed rule ignored",
        CTL,
        "if (rule == MLIP_RULE_FEED) {",
        "if (0 && rule == MLIP_RULE_FEED) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: a broken dwell rule ignored",
        CTL,
        "if (rule == MLIP_RULE_DWELL) {",
        "if (0 && rule == MLIP_RULE_DWELL) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: spindle speed upper bound removed",
        CTL,
        "rec->dwell_s <= MLIP_REC_RPM_MAX)) {",
        "rec->dwell_s <= 1e300)) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: spindle speed lower bound removed",
        CTL,
        "!(rec->dwell_s >= -MLIP_REC_RPM_MAX &&",
        "!(rec->dwell_s >= -1e300 &&",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: tool number need not be whole",
        CTL,
        "rec->dwell_s == floor(rec->dwell_s))) {",
        "rec->dwell_s == rec->dwell_s)) {",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: tool number range removed",
        CTL,
        "!(rec->dwell_s >= 0.0 && rec->dwell_s <= MLIP_REC_TOOL_MAX &&",
        "!(rec->dwell_s == rec->dwell_s &&",
        (UNIT_CTL,),
    ),
    Mutant(
        "record: coolant bits not checked",
        CTL,
        "if (rec->type == MLIP_REC_COOLANT &&",
        "if (0 && rec->type == MLIP_REC_COOLANT &&",
        (UNIT_CTL,),
    ),
    Mutant(
        "segment: a corrupt ring head ignored",
        CTL,
        "if (c->rx.corrupt && !c->prog.bad) {",
        "if (0 && c->rx.corrupt && !c->prog.bad) {",
        (UNIT_CTL,),
    ),
    # -- the rule set of every block (types.h), both sides of each bound
    Mutant(
        "rule: dwell upper bound (a day) removed",
        TYPES,
        "b->dwell_s <= MLIP_DWELL_MAX_S",
        "b->dwell_s <= 1e300",
        (UNIT_CTL, UNIT_GC),
    ),
    Mutant(
        "rule: dwell lower bound (0) removed",
        TYPES,
        "!(b->dwell_s >= 0.0 &&",
        "!(b->dwell_s >= -1e300 &&",
        (UNIT_CTL,),
    ),
    Mutant(
        "rule: target upper soft limit removed",
        TYPES,
        "b->target[k] <= m->axis[k].max_limit",
        "b->target[k] <= 1e300",
        (UNIT_CTL,),
    ),
    Mutant(
        "rule: target lower soft limit removed",
        TYPES,
        "b->target[k] >= m->axis[k].min_limit",
        "b->target[k] >= -1e300",
        (UNIT_CTL,),
    ),
    Mutant(
        "rule: target beyond the drive's 32-bit count accepted",
        TYPES,
        "counts > -2147483648.5 &&\n\t\t      counts < 2147483647.5",
        "counts > -1e300 &&\n\t\t      counts < 1e300",
        (UNIT_CTL,),
    ),
    Mutant(
        "rule: feed upper bound (1e6 mm/s) removed",
        TYPES,
        "b->feed_mm_s <= MLIP_FEED_MAX_MM_S",
        "b->feed_mm_s <= 1e300",
        (UNIT_CTL, UNIT_GC),
    ),
    Mutant(
        "rule: feed lower bound (0.001 mm/s) of a feed move removed",
        TYPES,
        "(b->rapid ? 0.0 : MLIP_FEED_MIN_MM_S)",
        "(b->rapid ? 0.0 : 0.0)",
        (UNIT_CTL, UNIT_GC),
    ),
    Mutant(
        "rule: a rapid's feed lower bound (0) removed",
        TYPES,
        "(b->rapid ? 0.0 : MLIP_FEED_MIN_MM_S)",
        "(b->rapid ? -1e300 : MLIP_FEED_MIN_MM_S)",
        (UNIT_CTL,),
    ),
    Mutant(
        "rule: tolerance upper bound (1000 mm) removed",
        TYPES,
        "b->tol_mm <= MLIP_TOL_MAX_MM",
        "b->tol_mm <= 1e300",
        (UNIT_CTL, UNIT_GC),
    ),
    Mutant(
        "rule: tolerance lower bound (0) removed",
        TYPES,
        "!(b->tol_mm >= 0.0 &&",
        "!(b->tol_mm >= -1e300 &&",
        (UNIT_CTL,),
    ),
    # -- the G-code reader
    Mutant(
        "reader: M1 refused (test_ctl_host once skipped on it)",
        "src/gcode/words.c",
        "if (c == 0 || c == 10 || c == 600) {",
        "if (c == 10) {\n\t\t\t\treturn mlip_gc_fail(e, line, w->col, MLIP_E_UNSUPPORTED, "
        '"M1");\n\t\t\t}\n'
        "\t\t\tif (c == 0 || c == 10 || c == 600) {",
        ("py:tests/py/test_ctl_host.py::test_sim_dwell_and_pauses_to_the_period",),
    ),
    Mutant(
        "reader: G4 P above a day accepted",
        "src/gcode/words.c",
        "if (b->g4 && !(b->p <= MLIP_DWELL_MAX_S)) {",
        "if (0 && b->g4 && !(b->p <= MLIP_DWELL_MAX_S)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: a target beyond the drive's count left to the backstop",
        "src/gcode/emit.c",
        "if (!(counts > -2147483648.5 && counts < 2147483647.5)) {",
        "if (0 && !(counts > -2147483648.5 && counts < 2147483647.5)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: G64 P negative accepted",
        "src/gcode/words.c",
        "if (b->g64 && b->has_p && !(b->p >= 0)) {",
        "if (0 && b->g64 && b->has_p && !(b->p >= 0)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: G53 in a modal G91 accepted",
        "src/gcode/gcode.c",
        "if (b->g53 && b->dist != 90 && !g->absolute) {",
        "if (0 && b->g53 && b->dist != 90 && !g->absolute) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: feed above 1e6 mm/s left to the backstop",
        "src/gcode/modal.c",
        "if (!(v <= MLIP_FEED_MAX_MM_S)) {",
        "if (0 && !(v <= MLIP_FEED_MAX_MM_S)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: feed below 0.001 mm/s left to the backstop",
        "src/gcode/modal.c",
        "if (!(v >= MLIP_FEED_MIN_MM_S)) {",
        "if (0 && !(v >= MLIP_FEED_MIN_MM_S)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: a move longer than a day accepted",
        "src/gcode/modal.c",
        "if (!(len / v <= MLIP_DWELL_MAX_S)) {",
        "if (0 && !(len / v <= MLIP_DWELL_MAX_S)) {",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: the block rule backstop removed",
        "src/gcode/emit.c",
        "g->broken_rule = mlip_block_check(g->m, &b);\n\tif (g->broken_rule != MLIP_RULE_OK ||"
        " c->sink",
        "g->broken_rule = 0;\n\tif (g->broken_rule != MLIP_RULE_OK || c->sink",
        (UNIT_GC,),
    ),
    Mutant(
        "reader: lines after the closing '%' run",
        "src/gcode/gcode.c",
        "\t\tif (g->content) {\n\t\t\tg->ended = 1;",
        "\t\tif (g->content) {\n\t\t\tg->ended = 0;",
        (UNIT_GC, "py:tests/py/test_cli.py"),
    ),
    Mutant(
        "reader: '%' opened and never closed accepted",
        "src/gcode/gcode.c",
        "if (g->percent && !g->ended) {",
        "if (0 && g->percent && !g->ended) {",
        (UNIT_GC,),
    ),
    # -- the machine's ranges
    Mutant(
        "config: CONTOUR_TOLERANCE above 1000 mm accepted",
        "src/machine/validate.c",
        "bad_max(&b, m, -1, TK_TOL, m->tolerance_mm, MLIP_CONFIG_TOL_MAX)",
        "bad_max(&b, m, -1, TK_TOL, m->tolerance_mm, 1e300)",
        (UNIT_CFG,),
    ),
    Mutant(
        "config: COUNTS_PER_UNIT below 0.1 accepted",
        "src/machine/validate.c",
        "if (!(a->counts_per_unit >= MLIP_CONFIG_COUNTS_MIN)) {",
        "if (0 && !(a->counts_per_unit >= MLIP_CONFIG_COUNTS_MIN)) {",
        (UNIT_CFG,),
    ),
    # -- what the tools say
    Mutant(
        "mlip-rt: a bad record met at rest logged at the block before it",
        "tools/mlip-rt.c",
        "int moving = e->from == MLIP_STATE_RUNNING || e->from == MLIP_STATE_HELD;",
        "int moving = 1;",
        (
            "py:tests/py/test_ctl_host.py::"
            "test_bad_record_met_in_a_dwell_names_where_the_machine_rests",
        ),
    ),
    Mutant(
        "checker: order test by the cancelling discriminant",
        "tools/lib/check.c",
        "\tif (!(p2 <= tol2)) {\n\t\treturn 0;\n\t}\n\tdouble h = sqrt((tol2 - p2) / len2);",
        "\tdouble ax = 0.0;\n\tfor (int k = 0; k < n; k++) {\n\t\tax += (x[k] - a[k]) * "
        "(x[k] - a[k]);\n\t}\n\tdouble disc = dot * dot - len2 * (ax - tol2);\n\tif (disc < "
        "0.0) {\n\t\treturn 0;\n\t}\n\tdouble h = sqrt(disc) / len2;\n\t(void)p2;",
        ("py:tests/py/test_cli.py::test_straight_move_at_a_tight_tolerance_passes_its_own_check",),
    ),
)


def sh(
    cmd: list[str], cwd: Path, env: dict[str, str] | None = None, timeout: float = 1800
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def copy_tree(dst: Path) -> None:
    """The tracked tree (as it is in the work tree), copied."""
    files = sh(["git", "ls-files", "-z"], ROOT).stdout.split("\0")
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (dst / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / f)


def build(tree: Path, tests: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    """The test binaries the mutant's tests are (a pytest case: everything)."""
    units = [f"b/tests/{t.split(':', 1)[1]}" for t in tests]
    every = not tests or any(t.startswith("py:") for t in tests)
    return sh(["make", "-s", "-j2", "BUILD=b", *(["all"] if every else units)], tree)


def run_test(tree: Path, test: str, env: dict[str, str]) -> str | None:
    """None when the test passes, else what failed: the cmocka cases of the
    binary, or the pytest case."""
    kind, what = test.split(":", 1)
    if kind == "unit":
        p = sh([str(tree / "b" / "tests" / what)], tree, env, timeout=600)
        if p.returncode == 0:
            return None
        cases = sorted(
            {
                ln.split("]", 1)[1].strip()
                for ln in (p.stdout + p.stderr).splitlines()
                if ln.startswith("[  FAILED  ] test_")
            }
        )
        return f"{what}: {', '.join(cases) or 'exit ' + str(p.returncode)}"
    p = sh(
        [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", what],
        tree,
        env,
        timeout=1200,
    )
    if p.returncode == 0:
        return None
    failed = [ln.split()[1] for ln in p.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))]
    return failed[0] if failed else f"{what}: exit {p.returncode}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="run the mutants whose name contains this")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--keep", help="scratch tree here (kept), instead of a temporary one")
    a = ap.parse_args()
    mutants = [m for m in MUTANTS if a.only is None or a.only in m.name]
    if a.list:
        for m in mutants:
            print(f"{m.name}  ({m.path}; {', '.join(m.tests)})")
        return 0
    for m in mutants:  # every mutant still applies to this tree
        n = (ROOT / m.path).read_text().count(m.old)
        if n != 1:
            print(f"mutate: '{m.name}': its text occurs {n} times in {m.path}", file=sys.stderr)
            return 2
    tmp = None
    if a.keep:
        tree = Path(a.keep)
        tree.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="mlip-mutate-")
        tree = Path(tmp.name)
    copy_tree(tree)
    env = dict(
        os.environ,
        MLIP_BUILD="b",
        PYTHONPATH=str(tree / "python"),
        MLIP_SHARED=os.environ.get("MLIP_SHARED", str(ROOT.parent / "shared")),
    )
    b = build(tree)
    if b.returncode != 0:
        print(f"mutate: the unmutated tree does not build:\n{b.stderr}", file=sys.stderr)
        return 2
    tests = sorted({t for m in mutants for t in m.tests})
    for t in tests:  # the guards pass on the real tree
        bad = run_test(tree, t, env)
        if bad is not None:
            print(f"mutate: {bad} fails before any mutation", file=sys.stderr)
            return 2
    rows, survived = [], 0
    for m in mutants:
        f = tree / m.path
        original = f.read_text()
        f.write_text(original.replace(m.old, m.new))
        t0 = time.monotonic()
        killer = None
        b = build(tree, m.tests)
        if b.returncode != 0:
            killer = "the build"
        else:
            for t in m.tests:
                killer = run_test(tree, t, env)
                if killer is not None:
                    break
        f.write_text(original)
        survived += killer is None
        rows.append((m.name, killer or "SURVIVED", time.monotonic() - t0))
        print(f"{m.name:<62} {killer or 'SURVIVED'}", flush=True)
    build(tree)  # leave a kept tree as it was
    print()
    print("| mutant | killed by |")
    print("|---|---|")
    for name, killer, _ in rows:
        print(f"| {name} | {killer} |")
    print(f"\nmutate: {len(rows) - survived} of {len(rows)} mutants killed")
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
