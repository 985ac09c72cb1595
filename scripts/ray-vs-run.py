#!/usr/bin/env python3
"""What Ray costs: `railgrip.ray.run` on a local Ray against `railgrip run --jobs N` on the same
campaign, one after the other in this process's machine, each into a fresh output folder.
Ray's start-up (ray.init) is timed apart. Prints one line per job and the ratio.

    scripts/ray-vs-run.py CAMPAIGN [--cpus 2] [--bin target/release/railgrip] [--work DIR]

CAMPAIGN may be a folder, an archive or s3://BUCKET/PREFIX (with the AWS_* variables set).
Needs the Python package (pip install ./crates/railgrip-py) and Ray (pip install ray).
"""

import argparse
import os
import shutil
import subprocess
import tempfile
import time


def compare(a: str, b: str):
    """The files (but timings.json) that differ between two output folders, and how many."""
    import filecmp

    def files(root: str):
        return sorted(
            os.path.relpath(os.path.join(d, f), root)
            for d, _, fs in os.walk(root)
            for f in fs
            if f != "timings.json"
        )

    fa, fb = files(a), files(b)
    differ = sorted(set(fa) ^ set(fb))
    differ += [f for f in fa if f in set(fb) and not filecmp.cmp(os.path.join(a, f), os.path.join(b, f), shallow=False)]
    return differ, len(fa)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("campaign")
    ap.add_argument("--cpus", type=int, default=2)
    ap.add_argument("--bin", default="target/release/railgrip")
    ap.add_argument("--work", default=None)
    a = ap.parse_args()
    if "://" not in a.campaign:
        a.campaign = os.path.abspath(a.campaign)  # Ray makes local paths absolute: so does the CLI run
    work = a.work or tempfile.mkdtemp(prefix="railgrip-ray-vs-run-")
    os.makedirs(work, exist_ok=True)
    cli_out, ray_out = os.path.join(work, "cli"), os.path.join(work, "ray")
    for d in (cli_out, ray_out):
        shutil.rmtree(d, ignore_errors=True)

    t = time.monotonic()
    r = subprocess.run(
        [a.bin, "run", a.campaign, "--out", cli_out, "--jobs", str(a.cpus)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    cli_s = time.monotonic() - t
    print(f"railgrip run --jobs {a.cpus}: {cli_s:.1f} s (exit {r.returncode})")

    import ray

    import railgrip
    import railgrip.ray

    t = time.monotonic()
    ray.init(num_cpus=a.cpus, include_dashboard=False, object_store_memory=200 * 1024 * 1024)
    start_s = time.monotonic() - t
    t = time.monotonic()
    result = railgrip.ray.run(a.campaign, ray_out, progress=lambda _line: None)
    ray_s = time.monotonic() - t
    ray.shutdown()
    print(f"ray.init(num_cpus={a.cpus}): {start_s:.1f} s")
    print(
        f"railgrip.ray.run: {ray_s:.1f} s ({len(result.records)} runs, {result.failed} failed); "
        f"stages of its models task: "
        + ", ".join(f"{name} {s:.1f} s" for name, s in result.stages)
    )
    print(f"ratio Ray / run: {ray_s / cli_s:.2f} (with Ray's start-up {(ray_s + start_s) / cli_s:.2f})")
    if "://" not in ray_out:
        differ, files = compare(cli_out, ray_out)
        print(f"outputs: {files} files; " + ("identical but timings.json" if not differ else f"DIFFER: {differ[:5]}"))
    print(f"railgrip {railgrip.__version__}, ray {ray.__version__}; outputs in {work}")


if __name__ == "__main__":
    main()
