"""Issue #77 item 3: can a model keep more of its gain on heavily H.264-coded phone views?

Two arms from the default, alike but for their training views' coding (share 1): ``control``
at CRF 18-30 (the coded recipe's range), ``heavy`` at CRF 30-44; each ``--iterations`` crops of
the coded recipe's ``phone-train`` on-the-fly source alone (the photographic run's scenes).
Then the gain table of ``view_blockiness.py`` for the default and both arms on the same held-out
phone frames. Resumable (a finished arm is kept).

    python experiments/scripts/coded_phone_probe.py runs/coded-phone \\
        --data runs/rdpd-light-photographs
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from in_focus_probe import arm_arguments  # beside this script
from view_blockiness import coded_psnr, held_out_frames

import dualpixel
from dualpixel.synthesis.on_the_fly import write_on_the_fly
from dualpixel.training import train
from dualpixel.training.recipe import load_recipe, phase_config, synth_config
from dualpixel.weights import resolve_tag

ARMS = {"control": [18, 30], "heavy": [30, 44]}
CRFS = (None, 18, 24, 30, 36, 44)
RECIPE = Path("recipes/rdpd-light-coded.yaml")


def make_arm(name: str, out: Path, data: Path, iterations: int, threads: int) -> Path:
    """Fine-tune the default on the phone source coded at the arm's CRF range; its weights."""
    recipe = load_recipe(RECIPE)
    step = next(s for s in recipe.data if s.name == "phone-train")
    config, source, fmt = synth_config(recipe, step, data)
    coding = {**config.view_coding, "share": 1.0, "quality": ARMS[name]}
    config = dataclasses.replace(config, view_coding=coding)
    write_on_the_fly(out / name / "source", source, fmt, config)
    start = str(resolve_tag("rdpd-light.v18"))
    settings = phase_config(recipe, 0, data, start)
    settings = dataclasses.replace(
        settings, synthetic_data=[str(out / name / "source")],
        val_data=[str(data / "data" / "phone-test")], val_limit=4, epochs=1,
        iterations_per_epoch=iterations, learning_rate=5e-5, threads=threads, workers=0,
        cache=True, tensorboard=False, checkpoint_minutes=10)
    run = out / name / "run"
    if not (run / "last.safetensors").is_file():
        train(settings, run, resume=(run / "last_state.pt").is_file(), progress=False)
    return run / "last.safetensors"


def gains(model: str, frames: list) -> list[float]:
    """Gain over the combined input (dB, green, mean of the frames) per CRF of CRFS."""
    loaded = dualpixel.load_model(model) if model.endswith(".safetensors") else model
    row = []
    for crf in CRFS:
        inputs, outputs = coded_psnr(frames, crf, [1.0] * len(frames), loaded)
        row.append(outputs - inputs)
    return row


def main() -> None:
    parser = arm_arguments(__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=8)
    args = parser.parse_args()
    models = {"rdpd-light (default)": "rdpd-light"}
    for name in ARMS:
        models[f"{name} (CRF {ARMS[name][0]}-{ARMS[name][1]})"] = str(
            make_arm(name, args.output, args.data, args.iterations, args.threads))
    names = ["clean" if c is None else f"CRF {c}" for c in CRFS]
    print(f"| model | {' | '.join(names)} |\n|---|{'---|' * len(CRFS)}")
    frames = held_out_frames(args.data / "data" / "phone-test", args.count)
    for label, model in models.items():
        row = gains(model, frames)
        print(f"| {label} | {' | '.join(f'{g:+.2f}' for g in row)} |", flush=True)


if __name__ == "__main__":
    main()
