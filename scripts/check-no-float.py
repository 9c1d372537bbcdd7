#!/usr/bin/env python3
"""Prove that the slave's default odometry path (`exact`) has no floating point on the STM32F103.

Builds robot-math for thumbv7m-none-eabi with the `objcheck` profile (release without LTO, so
the .rlib holds machine code), disassembles it with llvm-objdump, and walks the call graph
from the update entry points through every call relocation. It fails if anything reachable
calls a float routine (__aeabi_f*/__aeabi_d*, __adddf3, __mulsf3, ...), uses a VFP
instruction, or can panic (a bounds check or a division the compiler cannot prove safe: on
the board a panic halts the odometry); integer helpers (64-bit division, memcpy) are allowed.

Usage: python3 scripts/check-no-float.py               (from anywhere in the workspace)
       python3 scripts/check-no-float.py --self-test   (the f64 oracle must be flagged)
"""
import json
import re
import subprocess
import sys
from pathlib import Path

ROOTS = [
    "robot_math::exact::ExactOdometry::update_q16",
    "robot_math::exact::ExactOdometry::update_counts",
    # The slave's default: seed 004's carriage on the exact integrator.
    "robot_math::carriage::CarriageExact::update",
    "robot_math::carriage::CarriageExact::set_body",
    # The one odometry layer (robot_math::odometry::Odometry) running `exact`: what its
    # public `tick`, `update` and `set_pose` run for that method, and the readings' setters.
    "robot_math::odometry::estimator::Odometry::update_exact",
    "robot_math::odometry::estimator::Odometry::set_pose_exact",
    "robot_math::odometry::estimator::Odometry::record_tick",
    "robot_math::odometry::estimator::Odometry::set_counts",
    "robot_math::odometry::estimator::Odometry::set_abs",
    "robot_math::odometry::layout::AbsLayout::decode",
    # Tick-timestamp mode: edge decoding and interpolation to the update instant.
    "robot_math::sensors::QuadratureDecoder::edge",
    "robot_math::ticks::TickTracker::tick",
    "robot_math::ticks::TickTracker::position_q16",
    # Wire conversions the slave does on every update and every set-pose.
    "robot_math::exact::FixedPose::micrometres",
    "robot_math::exact::FixedPose::from_micrometres",
]
FLOAT = re.compile(r"^(__aeabi_[fd]|__aeabi_[il]2[fd]|__aeabi_ui2[fd]|__(add|sub|mul|div|neg|cmp|eq|ne|lt|le|gt|ge|unord)[sdt]f[23]|__(fix|float)(uns)?[sdt]i|__extend|__trunc|__pow|sin|cos|atan|sqrt|floor|round|libm::)")
VFP = re.compile(r"\bv(add|sub|mul|div|mov|ldr|str|cvt|cmp|sqrt|neg|abs|fma)\.?", re.I)


def main() -> int:
    roots = ROOTS
    if "--self-test" in sys.argv:
        # The checker must be able to fail: the f64 oracle is full of float calls.
        roots = ["robot_math::exact::ExactOracle::update"]
    root = Path(__file__).resolve().parent.parent
    build = subprocess.run(
        ["cargo", "build", "-p", "robot-math", "--profile", "objcheck",
         "--target", "thumbv7m-none-eabi", "--message-format=json"],
        cwd=root, capture_output=True, text=True)
    if build.returncode != 0:
        sys.stderr.write(build.stderr)
        return 2
    rlibs = [f for line in build.stdout.splitlines() if line.startswith("{")
             for msg in [json.loads(line)]
             if msg.get("reason") == "compiler-artifact" and msg["target"]["name"] == "robot_math"
             for f in msg["filenames"] if f.endswith(".rlib")]
    if not rlibs:
        print("error: no robot_math rlib in the build output", file=sys.stderr)
        return 2
    dis = subprocess.run(["llvm-objdump", "-d", "-r", "--demangle", rlibs[0]],
                         capture_output=True, text=True).stdout

    # function name (hash stripped) -> (instructions, call targets)
    funcs, current = {}, None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if m:
            current = re.sub(r"::h[0-9a-f]{16}$", "", m.group(1))
            funcs[current] = ([], set())
            continue
        if current is None:
            continue
        m = re.search(r"R_ARM_THM_(CALL|JUMP24)\s+(.+)$", line)
        if m:
            funcs[current][1].add(re.sub(r"::h[0-9a-f]{16}$", "", m.group(2).strip()))
        elif line.strip():
            funcs[current][0].append(line)

    missing = [r for r in roots if r not in funcs]
    if missing:
        print(f"error: entry points not found in the object code: {missing}", file=sys.stderr)
        return 2
    seen, todo, external, problems = set(), list(roots), set(), []
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        if f not in funcs:
            external.add(f)
            if FLOAT.search(f):
                problems.append(f"calls float routine {f}")
            if f.startswith("core::panicking") or "panic" in f:
                problems.append(f"can panic: {f}")
            continue
        insns, calls = funcs[f]
        for i in insns:
            if VFP.search(i.split(";")[0].split("\t", 2)[-1] if "\t" in i else ""):
                problems.append(f"{f}: VFP instruction: {i.strip()}")
        todo.extend(calls)
    local = sorted(seen - external)
    print(f"exact update path on thumbv7m-none-eabi: {len(local)} functions, "
          f"{sum(len(funcs[f][0]) for f in local)} instructions")
    for f in local:
        print(f"  {f}")
    print("external calls: " + (", ".join(sorted(external)) or "none"))
    if "--self-test" in sys.argv:
        ok = bool(problems)
        print("self-test: " + ("the oracle's float calls were caught" if ok else "FAILED to catch floats"))
        return 0 if ok else 1
    if problems:
        print("FOUND:\n  " + "\n  ".join(problems))
        return 1
    print("no float routines, VFP instructions or panics reachable")
    return 0


if __name__ == "__main__":
    sys.exit(main())
