#!/usr/bin/env python3
"""Paired mission comparison: runs two vantage-sim configurations over the same image spacings and budgets
and prints, per figure of summary.json, both means, the mean paired difference, its standard error and how
many runs moved up. Single missions swing by up to 13 coverage points with any change (they are chaotic), so
a change is judged by the paired difference over many spacings (core/frontend/EXPERIMENTS.md).

Example (the default run against a scratch switch read from the environment):
  targets/sim/tools/paired_missions.py --out /tmp/pairs \\
      --base build/release/targets/sim/vantage-sim --variant build/release/targets/sim/vantage-sim \\
      --variant-env SCR_X=1 --budgets 270,600

Each run is `<command> --quiet --budget B --image-spacing S --out OUT/<name>/<B>/<S>`. With --reuse a run
whose summary.json is already there is not run again, so a base can be shared between comparisons (give
each configuration its own --base-name / --variant-name; a rebuilt binary needs a fresh --out)."""
import argparse
import concurrent.futures
import json
import math
import os
import shlex
import subprocess
import sys

FIGURES = [
    # (summary.json key, printed name, scale)
    ("coverage", "coverage %", 100.0),
    ("verified_coverage", "verified coverage %", 100.0),
    ("model_coverage", "model coverage %", 100.0),
    ("mean_sigma", "avg sigma", 1.0),
    ("accuracy_rms_confirmed", "RMS confirmed", 1.0),
    # The missions' own consistency: of the precise primitives (sigma below the target), the share within 3
    # of their sigmas of the surface (0.997 for a consistent filter; sim_hal/README.md (f)).
    (lambda run: run["precise_verified"] / run["precise"] if run.get("precise") else None,
     "precise verified %", 100.0),
    ("gross", "more than a unit off", 1.0),
    # The same without ground truth, from the EKF's innovations (core/estimation/nis_histogram.hpp): the median
    # NIS over chi-square(2)'s and the share beyond its 95 % point (1 and 5 % when honest).
    (lambda run: run.get("innovations", {}).get("median_scale"), "innovation scale", 1.0),
    (lambda run: run.get("innovations", {}).get("beyond_95"), "innovations past 95 %", 100.0),
    ("primitives", "primitives", 1.0),
    ("nbv_iterations", "NBV iterations", 1.0),
]


def spacing_list(text):
    """'3:5.625:0.125' (first:last:step, inclusive) or '3,4,5'."""
    if ":" in text:
        first, last, step = (float(x) for x in text.split(":"))
        if step <= 0 or last < first:
            raise argparse.ArgumentTypeError(f"--spacings: bad range {text!r}")
        count = int(round((last - first) / step)) + 1
        return [round(first + i * step, 6) for i in range(count)]
    return [float(x) for x in text.split(",")]


def env_pairs(items):
    env = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"paired_missions: environment setting {item!r} is not KEY=VALUE")
        env[key] = value
    return env


def run_one(command, env, budget, spacing, out_dir, reuse):
    summary = os.path.join(out_dir, "summary.json")
    if reuse and os.path.exists(summary):
        return summary
    os.makedirs(out_dir, exist_ok=True)
    argv = shlex.split(command) + ["--quiet", "--budget", str(budget), "--image-spacing", f"{spacing:g}",
                                   "--out", out_dir]
    with open(os.path.join(out_dir, "stdout.txt"), "w") as log:
        status = subprocess.run(argv, env={**os.environ, **env}, stdout=log, stderr=subprocess.STDOUT).returncode
    # vantage-sim's exit codes: 0 goals reached, 2 budget exhausted first, 3 planner failure (each with its
    # report written); 1 bad input or simulator error.
    if status not in (0, 2, 3) or not os.path.exists(summary):
        raise RuntimeError(f"{' '.join(argv)} failed with status {status} (see {out_dir}/stdout.txt)")
    return summary


def read_summary(path):
    with open(path) as f:
        return json.load(f)


def figure(run, key):
    """A summary.json field, or a figure derived from the run's fields (None when it has none)."""
    return key(run) if callable(key) else run.get(key)


def paired_table(budget, base_runs, variant_runs):
    lines = [f"budget {budget}: {len(base_runs)} spacings (mean base -> variant, paired difference, standard "
             "error, runs up)"]
    for key, name, scale in FIGURES:
        values = [(figure(b, key), figure(v, key)) for b, v in zip(base_runs, variant_runs)]
        pairs = [(b * scale, v * scale) for b, v in values if b is not None and v is not None]
        if not pairs:
            continue
        n = len(pairs)
        diffs = [v - b for b, v in pairs]
        mean_diff = sum(diffs) / n
        se = math.sqrt(sum((d - mean_diff) ** 2 for d in diffs) / (n - 1) / n) if n > 1 else float("nan")
        up = sum(1 for d in diffs if d > 0)
        base_mean = sum(b for b, _ in pairs) / n
        variant_mean = sum(v for _, v in pairs) / n
        lines.append(f"  {name:22s} {base_mean:12.5g} -> {variant_mean:12.5g}   {mean_diff:+.5g} ({se:.3g})   {up} of {n}")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, help="folder for every run's report")
    parser.add_argument("--base", required=True, help="base command (vantage-sim and its options)")
    parser.add_argument("--variant", required=True, help="variant command")
    parser.add_argument("--base-env", action="append", help="KEY=VALUE for the base's environment")
    parser.add_argument("--variant-env", action="append", help="KEY=VALUE for the variant's environment")
    parser.add_argument("--base-name", default="base")
    parser.add_argument("--variant-name", default="variant")
    parser.add_argument("--spacings", type=spacing_list, default=spacing_list("3:5.625:0.125"),
                        help="image spacings: first:last:step or a comma list (default 3:5.625:0.125, 22 runs)")
    parser.add_argument("--budgets", default="600", help="comma list of image budgets (default 600)")
    parser.add_argument("--jobs", type=int, default=2, help="missions run at once (default 2)")
    parser.add_argument("--reuse", action="store_true", help="keep the runs whose summary.json exists")
    args = parser.parse_args()
    if args.base_name == args.variant_name:
        raise SystemExit("paired_missions: --base-name and --variant-name must differ (their runs share --out)")
    try:
        budgets = [int(b) for b in args.budgets.split(",")]
    except ValueError:
        raise SystemExit(f"paired_missions: --budgets {args.budgets!r} is not a comma list of integers")
    if args.jobs < 1:
        raise SystemExit("paired_missions: --jobs must be at least 1")
    configs = [(args.base_name, args.base, env_pairs(args.base_env)),
               (args.variant_name, args.variant, env_pairs(args.variant_env))]
    jobs = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for budget in budgets:
            for spacing in args.spacings:
                for name, command, env in configs:
                    out_dir = os.path.join(args.out, name, str(budget), f"{spacing:g}")
                    jobs[(name, budget, spacing)] = pool.submit(run_one, command, env, budget, spacing, out_dir,
                                                                args.reuse)
        try:
            summaries = {key: read_summary(job.result()) for key, job in jobs.items()}
        except RuntimeError as error:
            raise SystemExit(f"paired_missions: {error}")
    for budget in budgets:
        base_runs = [summaries[(args.base_name, budget, s)] for s in args.spacings]
        variant_runs = [summaries[(args.variant_name, budget, s)] for s in args.spacings]
        print(paired_table(budget, base_runs, variant_runs))


if __name__ == "__main__":
    sys.exit(main())
