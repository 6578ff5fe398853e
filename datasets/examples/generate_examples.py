#!/usr/bin/env python3
"""Writes the EXAMPLE inputs of `dexjoco-data stats` (standard library only, seeded).

    python3 datasets/examples/generate_examples.py

- language-eval/: an evaluation tree in the layout the DexJoCo reference evaluator
  writes for the iPad language study: <config>/bimanual_unlock_ipad_seed<s>/
  episode_XX_{success|failure}_{<digits>|no_password_input}/, plus instructions.csv.
- success-table/: <policy>/<task>[_rand_full]_seed<s>/success_rate_<n>_<episodes>.txt
  marker files for two made-up policies.

Every number in them is drawn from made-up distributions below. They exist to show
what the command does; they are NOT evaluation results of any policy.
"""

import random
import shutil
from pathlib import Path

HERE = Path(__file__).resolve().parent
SEEDS = [0, 1, 2]

EXAMPLE_NOTE = """# EXAMPLE INPUT: not results

Made up by `datasets/examples/generate_examples.py` (seeded, standard library only) to
show what `dexjoco-data stats` does. No policy was evaluated to make these files.
Regenerate with `python3 datasets/examples/generate_examples.py`.
"""

# Instruction configs of the study (labels and instructions as in the DexJoCo paper's
# appendix table); the expected answer is the password the instruction asks for.
INSTRUCTIONS = [
    ("password_1", "1", "1", "Grasp the iPad and enter the password 1 to unlock the device."),
    ("password_2", "2", "2", "Grasp the iPad and enter the password 2 to unlock the device."),
    ("password_4", "4", "4", "Grasp the iPad and enter the password 4 to unlock the device."),
    ("password_1+1", "1+1", "2", "Grasp the iPad and enter the result of 1+1 as the password to unlock the device."),
    ("password_2+2", "2+2", "4", "Grasp the iPad and enter the result of 2+2 as the password to unlock the device."),
    ("password_two", "two", "2", "Grasp the iPad and enter the password two to unlock the device."),
    (
        "password_one_plus_one",
        "one plus one",
        "2",
        "Grasp the iPad and enter the result of one plus one as the password to unlock the device.",
    ),
]
# A made-up policy that mostly ignores the instruction: a fixed bias over what it enters,
# and a small chance of following the instruction.
BIAS = {"1": 0.14, "2": 0.30, "3": 0.28, "4": 0.06, "5": 0.06, "12": 0.04, "none": 0.12}
FOLLOW = 0.12
EPISODES = 20

TASKS = [
    "hammer_nail", "click_mouse", "pick_bucket", "pinch_tongs", "fold_glasses", "water_plant",
    "bimanual_unlock_ipad", "bimanual_hanoi", "bimanual_assembly", "bimanual_microwave_cook",
    "bimanual_photograph",
]
POLICIES = ["policy-a", "policy-b"]
TABLE_EPISODES = 50


def reset(folder):
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    (folder / "EXAMPLE.md").write_text(EXAMPLE_NOTE)


def language_eval(rng):
    root = HERE / "language-eval"
    reset(root)
    with open(root / "instructions.csv", "w") as f:
        f.write("config,instruction,expected,prompt\n")
        for config, label, expected, prompt in INSTRUCTIONS:
            f.write(f'{config},{label},{expected},"{prompt}"\n')
    outputs, weights = list(BIAS), list(BIAS.values())
    for config, _label, expected, _prompt in INSTRUCTIONS:
        for seed in SEEDS:
            run = root / config / f"bimanual_unlock_ipad_seed{seed}"
            run.mkdir(parents=True)
            successes = 0
            for ep in range(EPISODES):
                out = expected if rng.random() < FOLLOW else rng.choices(outputs, weights)[0]
                ok = out == expected
                successes += ok
                suffix = "no_password_input" if out == "none" else out
                folder = run / f"episode_{ep:02d}_{'success' if ok else 'failure'}_{suffix}"
                folder.mkdir()
                # Git keeps no empty folders; the real ones hold the camera videos.
                (folder / ".keep").write_text("")
            (run / f"success_rate_{successes}_{EPISODES}.txt").write_text("")


def success_table(rng):
    root = HERE / "success-table"
    reset(root)
    for policy in POLICIES:
        for task in TASKS:
            base = rng.uniform(0.05, 0.9)
            for regime, factor in [("", 1.0), ("_rand_full", rng.uniform(0.3, 0.9))]:
                for seed in SEEDS:
                    p = min(1.0, max(0.0, base * factor + rng.gauss(0, 0.04)))
                    k = sum(rng.random() < p for _ in range(TABLE_EPISODES))
                    run = root / policy / f"{task}{regime}_seed{seed}"
                    run.mkdir(parents=True)
                    (run / f"success_rate_{k}_{TABLE_EPISODES}.txt").write_text("")


def main():
    rng = random.Random(20260522)
    language_eval(rng)
    success_table(rng)
    print(f"wrote {HERE / 'language-eval'} and {HERE / 'success-table'}")


if __name__ == "__main__":
    main()
