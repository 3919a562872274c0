"""The ROS-free check of scripts/check_core --quick: every source of every ROS-free target of a build
tree (its ros_free_targets.txt), preprocessed with the exact command the build compiles it with
(compile_commands.json), must not reach a ROS header: the poison's #error would stop it. Also checks
that each such target has the poison first on its include path. Prints each offender; exit 1 if any.

Usage: ros_free_sources.py BUILD_DIR
"""
import concurrent.futures
import json
import os
import re
import shlex
import subprocess
import sys


def main():
    build = os.path.abspath(sys.argv[1])
    with open(os.path.join(build, "ros_free_targets.txt")) as f:
        targets = [t for t in f.read().split() if t]
    with open(os.path.join(build, "compile_commands.json")) as f:
        commands = json.load(f)
    poison = os.path.join(build, "ros_poison")
    by_target = {t: [] for t in targets}
    for c in commands:
        argv = shlex.split(c["command"])
        out = argv[argv.index("-o") + 1] if "-o" in argv else ""
        m = re.match(r"CMakeFiles/([^/]+)\.dir/", out)
        if m and m.group(1) in by_target:
            by_target[m.group(1)].append((c["directory"], argv, c["file"]))
    problems = []
    for t, units in by_target.items():
        if not units:
            problems.append("%s: no compile command in %s (not built in this tree?)" % (t, build))
        for _, argv, src in units:
            includes = [a[2:] for a in argv if a.startswith("-I")]
            if not includes or includes[0] != poison:
                problems.append("%s: %s compiles without the ROS poison first on its include path" % (t, src))

    def preprocess(unit):
        directory, argv, src = unit
        i = argv.index("-o")
        cmd = [a for a in argv[:i] + argv[i + 2:] if a != "-c"] + ["-E", "-o", os.devnull]
        r = subprocess.run(cmd, cwd=directory, capture_output=True, text=True)
        if r.returncode == 0:
            return None
        hit = re.search(r'#error "(ROS [^"]*)"', r.stderr)
        return "%s: %s" % (src, hit.group(1) if hit else "does not preprocess: " + r.stderr.strip()[:400])

    units = [u for us in by_target.values() for u in us]
    with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        problems += [p for p in pool.map(preprocess, units) if p]
    for p in problems:
        print("check_core: " + p)
    if not problems:
        print("check_core: %d ROS-free targets, %d sources preprocessed with their build flags: no ROS header"
              % (len(targets), len(units)))
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
