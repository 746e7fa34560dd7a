"""paired_missions.py's table from made-up summaries: each figure's means, paired difference, standard error
and count of runs up, the derived share of precise primitives verified among them, and a figure a run does
not have left out."""
import importlib.util
import sys

spec = importlib.util.spec_from_file_location("paired_missions", sys.argv[1])
paired_missions = importlib.util.module_from_spec(spec)
spec.loader.exec_module(paired_missions)

base = [{"coverage": 0.5, "precise": 100, "precise_verified": 50},
        {"coverage": 0.6, "precise": 200, "precise_verified": 120}]
variant = [{"coverage": 0.55, "precise": 100, "precise_verified": 60},
           {"coverage": 0.62, "precise": 100, "precise_verified": 70}]


def table_rows():
    """The table's rows by figure name: means, difference, standard error and runs up, as words."""
    table = paired_missions.paired_table(270, base, variant).splitlines()
    return {line[2:24].strip(): line[24:].split() for line in table[1:]}


rows = table_rows()
failures = []


def expect(name, wanted):
    got = rows.get(name)
    if got != wanted:
        failures.append(f"{name}: {got} != {wanted}")


# Coverage: 55 -> 58.5, differences +5 and +2: mean +3.5, standard error sqrt(4.5 / 1 / 2) = 1.5.
expect("coverage %", ["55", "->", "58.5", "+3.5", "(1.5)", "2", "of", "2"])
# Precise verified: 50 and 60 % -> 60 and 70 %: +10 each.
expect("precise verified %", ["55", "->", "65", "+10", "(0)", "2", "of", "2"])
if "innovation scale" in rows:
    failures.append("the innovations' figures are printed for runs without them")
if "verified coverage %" in rows:
    failures.append("a figure no run has is printed")
# A run without precise primitives has no share: the pair is left out.
base[1]["precise"] = 0
rows = table_rows()
expect("precise verified %", ["50", "->", "60", "+10", "(nan)", "1", "of", "1"])
# The innovations' figures from the nested summary (median scale, share beyond the 95 % point in %).
for run, scale, beyond in zip(base + variant, [1.0, 1.2, 1.1, 1.6], [0.05, 0.07, 0.06, 0.09]):
    run["innovations"] = {"median_scale": scale, "beyond_95": beyond}
rows = table_rows()
expect("innovation scale", ["1.1", "->", "1.35", "+0.25", "(0.15)", "2", "of", "2"])
expect("innovations past 95 %", ["6", "->", "7.5", "+1.5", "(0.5)", "2", "of", "2"])
if failures:
    print("\n".join(failures))
    sys.exit(1)
print("paired table: figures, derived share and missing figures as expected")
