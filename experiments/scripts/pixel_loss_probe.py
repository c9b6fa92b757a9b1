"""Issue #77: does a Charbonnier pixel term (a smooth L1) instead of Eq. 16's MSE help the
default on real views (docs/log/2026-12-04-pixel-loss.md)?

Where the views hold no trace of a band (a kernel's zero, the brick wall of dev scene 02 in
docs/formation.md) a network trained for the mean squared error returns the mean of what could
be there; an L1-like term returns a median, which commits to one of them. Two arms from the
default, alike but for the pixel term (``TrainConfig.pixel_loss``): ``control`` (MSE) and
``charbonnier``, each trained, then scored, as ``in_focus_probe.py`` does (the coded recipe's
sources, 600 iterations of 8 crops of 256 px at 5e-5 cosine; the dev scenes, three clean
photographic held-out sets, `check-model` on dp-real-nogt). Resumable.

    python experiments/scripts/pixel_loss_probe.py runs/pixel-loss \\
        --data runs/rdpd-light-photographs
"""

from __future__ import annotations

from in_focus_probe import (  # beside this script
    START,
    arm_arguments,
    make_arm,
    print_table,
    score_all,
)

ARMS = {"charbonnier": {"pixel_loss": "charbonnier"}, "control": {}}


def main() -> None:
    args = arm_arguments(__doc__.splitlines()[0]).parse_args()
    for name, training in ARMS.items():  # each arm scored before the next trains
        weights = make_arm(name, (0.0, 0.0), args.output, args.data, args.iterations,
                           args.threads, **training)
        score_all({name: str(weights)}, args.output, args.data)
    print_table(score_all({"default": START}, args.output, args.data))


if __name__ == "__main__":
    main()
