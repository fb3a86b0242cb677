#!/usr/bin/env python3
"""Mutation suite: each weakening of Theorem 1's code must be killed by a property test.

Copies the source tree to a scratch folder, configures a lean build there (only the test
binaries the mutants name), builds once, checks that every named test passes on the unmutated
code, then for each mutant: applies its exact text replacement (the old text must occur exactly
once in its file, or the suite fails: a mutant whose code moved can never silently "pass"),
rebuilds incrementally, runs the tests named for it, and restores the file. Fails if a mutant
survives (no named test fails), does not compile, or is stale. Prints mutant -> killing tests.

    python3 tools/mutation/run_mutants.py [--source DIR] [--scratch DIR] [--only NAME ...]

Debian's python3 only (no third-party modules). The mutants are in mutants.py beside this file.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mutants import MUTANTS  # noqa: E402

# Per test run: a property test that hangs on a mutant counts as killing it (the mutant made it
# fail to finish), but the suite must still fit its budget.
TEST_TIMEOUT_S = 300


def log(msg):
    print(msg, flush=True)


def copy_tree(source, dest):
    """The tracked and untracked-but-not-ignored files when source is a git checkout; otherwise
    everything but build folders."""
    if os.path.exists(dest):
        shutil.rmtree(dest)
    files = None
    if os.path.exists(os.path.join(source, ".git")) and shutil.which("git"):
        r = subprocess.run(["git", "-C", source, "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                           capture_output=True)
        if r.returncode == 0:
            files = [f for f in r.stdout.decode().split("\0") if f]
    if files is None:
        shutil.copytree(source, dest, symlinks=True,
                        ignore=shutil.ignore_patterns("build", "build-*", ".git"))
        return
    for f in files:
        src = os.path.join(source, f)
        if not os.path.lexists(src):  # deleted in the working tree
            continue
        dst = os.path.join(dest, f)
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        if os.path.islink(src):
            os.symlink(os.readlink(src), dst)
        else:
            shutil.copy2(src, dst)


def parse_test(spec):
    """'test_rt:Group.name' -> (binary, group, name)."""
    binary, rest = spec.split(":", 1)
    group, name = rest.split(".", 1)
    return binary, group, name


def run_test(build, spec):
    """True when the test passes, False when it fails (or times out, or crashes)."""
    binary, group, name = parse_test(spec)
    exe = os.path.join(build, "bin", binary)
    try:
        r = subprocess.run([exe, "-sg", group, "-sn", name], capture_output=True, timeout=TEST_TIMEOUT_S,
                           cwd=os.path.join(build))
    except subprocess.TimeoutExpired:
        return False, "timed out after %d s" % TEST_TIMEOUT_S
    out = r.stdout.decode(errors="replace")
    # CppUTest prints "OK (n tests, 1 ran, ...)" on success; a name that matches nothing runs 0 tests
    if r.returncode == 0 and ", 1 ran," not in out:
        raise SystemExit("mutation: %s matched no test (renamed? fix tools/mutation/mutants.py)\n%s" % (spec, out))
    return r.returncode == 0, out[-2000:]


def build(build_dir, targets):
    r = subprocess.run(["cmake", "--build", build_dir, "-j", str(os.cpu_count() or 2), "--target"] + targets,
                       capture_output=True)
    return r.returncode == 0, (r.stdout + r.stderr).decode(errors="replace")[-4000:]


def test_area(source, binary):
    """The top-level folder of tests/ (an area of HAPTIC_TEST_AREAS) whose CMakeLists.txt declares binary."""
    decl = "haptic_add_cpputest(" + binary
    for root, _dirs, files in os.walk(os.path.join(source, "tests")):
        if "CMakeLists.txt" in files:
            with open(os.path.join(root, "CMakeLists.txt"), encoding="utf-8") as f:
                if re.search(re.escape(decl) + r"\b", f.read()):
                    return os.path.relpath(root, os.path.join(source, "tests")).split(os.sep)[0]
    raise SystemExit("mutation: no tests/**/CMakeLists.txt declares %s" % binary)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", default=os.path.normpath(os.path.join(here, "..", "..")))
    ap.add_argument("--scratch", default=None, help="scratch folder (default: <source>/build-mutation)")
    ap.add_argument("--only", nargs="*", default=None, help="run only these mutants (by name)")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    a = ap.parse_args()
    t0 = time.monotonic()
    mutants = [m for m in MUTANTS if a.only is None or m["name"] in a.only]
    if a.list:
        for m in mutants:
            log("%-28s %-30s %s" % (m["name"], m["file"], m["what"]))
        return 0
    if a.only is not None and len(mutants) != len(a.only):
        raise SystemExit("mutation: unknown mutant in --only (see --list)")
    source = os.path.abspath(a.source)
    scratch = os.path.abspath(a.scratch or os.path.join(source, "build-mutation"))
    # The build folder inside the copy, as build/ in a checkout: with ccache's base_dir set to the
    # copy, its compile lines are those of the checkout's build/ with base_dir there (tools/test.sh),
    # so the lean build is mostly cache hits after the main build. Same flags as tools/test.sh's build
    # (warnings stay errors: a mutant must compile cleanly, or its record is fixed).
    tree = os.path.join(scratch, "src")
    bdir = os.path.join(tree, "build")

    # 1. Stale mutants fail before anything is built: the old text occurs exactly once.
    stale = []
    for m in mutants:
        with open(os.path.join(source, m["file"]), encoding="utf-8") as f:
            n = f.read().count(m["old"])
        if n != 1:
            stale.append("%s: its old text occurs %d times in %s (the code moved: re-point the record)" % (m["name"], n, m["file"]))
    if stale:
        for s in stale:
            log("mutation: STALE " + s)
        return 1

    # 2. Copy, configure lean, build once.
    log("mutation: copying %s to %s" % (source, tree))
    copy_tree(source, tree)
    binaries = sorted({parse_test(t)[0] for m in mutants for t in m["tests"]})
    areas = sorted({test_area(source, b) for b in binaries})
    cfg = ["cmake", "-S", tree, "-B", bdir, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
           "-DHAPTIC_BUILD_BENCHMARKS=OFF", "-DHAPTIC_TEST_AREAS=" + ";".join(areas)]
    if shutil.which("ccache"):
        cfg += ["-DCMAKE_CXX_COMPILER_LAUNCHER=ccache", "-DCMAKE_C_COMPILER_LAUNCHER=ccache"]
        os.environ["CCACHE_BASEDIR"] = tree
    r = subprocess.run(cfg, capture_output=True)
    if r.returncode != 0:
        log((r.stdout + r.stderr).decode(errors="replace"))
        raise SystemExit("mutation: configure failed")
    ok, out = build(bdir, binaries)
    if not ok:
        log(out)
        raise SystemExit("mutation: the unmutated build failed")
    log("mutation: built %s in %.0f s" % (", ".join(binaries), time.monotonic() - t0))

    # 3. Every named test passes on the unmutated code (a test failing anyway kills nothing).
    tests = sorted({t for m in mutants for t in m["tests"]})
    failing = []
    for t in tests:
        passed, out = run_test(bdir, t)
        if not passed:
            failing.append(t)
            log("mutation: %s FAILS on the unmutated code:\n%s" % (t, out))
    if failing:
        raise SystemExit("mutation: %d named test(s) fail without a mutant" % len(failing))
    log("mutation: %d named tests pass on the unmutated code (%.0f s so far)" % (len(tests), time.monotonic() - t0))

    # 4. Each mutant: apply, rebuild, run its tests, restore.
    rows, failures = [], []
    for m in mutants:
        path = os.path.join(tree, m["file"])
        with open(path, encoding="utf-8") as f:
            original = f.read()
        t1 = time.monotonic()
        try:
            with open(path, "w", encoding="utf-8") as f:
                f.write(original.replace(m["old"], m["new"], 1))
            ok, out = build(bdir, sorted({parse_test(t)[0] for t in m["tests"]}))
            if not ok:
                failures.append(m["name"])
                rows.append((m["name"], "DOES NOT COMPILE", []))
                log("mutation: %s does not compile (a mutant must build):\n%s" % (m["name"], out))
                continue
            killers, survivors = [], []
            for t in m["tests"]:
                passed, _ = run_test(bdir, t)
                (survivors if passed else killers).append(t)
            status = "killed" if killers else "SURVIVED"
            if not killers:
                failures.append(m["name"])
            rows.append((m["name"], status, killers))
            log("mutation: %-28s %-8s by %d of %d named tests (%.0f s)" % (m["name"], status, len(killers), len(m["tests"]),
                                                                          time.monotonic() - t1))
        finally:
            with open(path, "w", encoding="utf-8") as f:
                f.write(original)

    # 5. The table, printed and kept in <scratch>/mutants.md.
    table = ["| mutant | what | file | status | killed by |", "|---|---|---|---|---|"]
    for (name, status, killers), m in zip(rows, mutants):
        table.append("| %s | %s | %s | %s | %s |" % (name, m["what"], m["file"], status,
                                                   "<br>".join(k.split(":", 1)[1] for k in killers) or "-"))
    table.append("")
    table.append("mutation: %d mutants, %d killed, %d not (%s); wall time %.0f s" % (
        len(rows), len(rows) - len(failures), len(failures), ", ".join(failures) or "none", time.monotonic() - t0))
    log("\n" + "\n".join(table))
    with open(os.path.join(scratch, "mutants.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(table) + "\n")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
