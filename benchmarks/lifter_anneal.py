"""What a long training would give if its learning rate were brought down now: a copy of a running
profile's checkpoint trained on for ``--steps`` more steps by the same loop, with the rate decaying
from where the run is to the profile's final rate over exactly those steps, then scored with the
held-out protocol (the 40 sequences, clean and noisy 2D) and on the later sources' takes.

A long run's checkpoint mid-schedule is scored at a high learning rate, which flatters nothing:
its figures wander by millimetres between readings (docs/reports/lifter.md). Annealing a copy says
what the weights are worth, so "train for as long as it pays" is decided on figures. The running
training's checkpoint is only read.

Usage: DANCE3D_MOCAP=../shared/mocap python -m benchmarks.lifter_anneal [--profile long] [--steps 2000]
           [--out benchmarks/results/lifter_anneal_<step>.json]
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from benchmarks.lifter_checkpoint import profile_run
from pipeline.core.storage import write_json


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--profile", default="long")
    parser.add_argument("--steps", type=int, default=2000, help="steps of the decay (default 2000)")
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the profile's own")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    import torch

    from pipeline.motion.lifting import train as training
    from pipeline.motion.lifting.evaluate import format_report

    cfg, train, val, later, source = profile_run(args.profile, args.mocap, args.checkpoint)
    state = torch.load(source, weights_only=False)
    start, rate = state["step"], state["optimiser"]["param_groups"][0]["lr"]
    # The loop resumes the copy with its optimiser and data order (each step's batch is seeded by its
    # number); only the scheduler's factor is changed, to reach lr_final at start + steps.
    state["scheduler"]["gamma"] = (cfg.lr_final / rate) ** (1.0 / args.steps)
    work = Path(tempfile.mkdtemp(prefix="dance3d-anneal-"))
    copy = work / "annealed.pt"
    torch.save(state, copy)
    print(f"{source.name}: annealing from step {start} (learning rate {rate:.2e}) to {cfg.lr_final:.0e} "
          f"over {args.steps} steps", flush=True)
    started = time.monotonic()
    result = training.train_lifter(replace(cfg, steps=start + args.steps), train, val, checkpoint=copy,
                                   checkpoint_minutes=1e9)
    seconds = time.monotonic() - started
    heldout = result.metrics["heldout"]
    later_result = training.evaluate(result.model, later, cfg)["heldout"] if later else None
    shutil.rmtree(work)
    print(format_report(heldout))
    out = args.out or Path(f"benchmarks/results/lifter_anneal_{start}.json")
    write_json(out, {"profile": args.profile, "from_step": start, "from_learning_rate": rate,
                     "anneal_steps": args.steps, "final_learning_rate": cfg.lr_final,
                     "seconds_with_evaluation": round(seconds, 1), "clean": heldout["clean"],
                     "noisy": heldout["noisy"],
                     "sources": {k: {"clean": v["clean"], "noisy": v["noisy"]} for k, v in heldout["sources"].items()},
                     "later": ({"clean": later_result["clean"], "noisy": later_result["noisy"],
                                "sources": {k: v["clean"] for k, v in later_result["sources"].items()}}
                               if later_result else None)})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
