import json
import math
import re

import pytest
import torch
import yaml
from click.testing import CliRunner

from dualpixel.cli.main import cli
from dualpixel.errors import InputFileError, ParameterError
from dualpixel.models import build_model, load_model
from dualpixel.training import DeblurLoss, load_config, train
from dualpixel.training.trainer import Trainer
from tests.conftest import write_dpdd_pairs


def tiny_config(data, **overrides):
    values = dict(model="rdpd", width=0.125, synthetic_data=str(data), patch_size=32,
                  sequence_batch=2, sequence_frames=2, epochs=2, iterations_per_epoch=3,
                  workers=0, learning_rate=1e-3, tensorboard=False)
    values.update(overrides)
    return load_config(None, values)


def test_tiny_model_overfits_a_tiny_batch(tiny_synthetic_dataset):
    from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset

    torch.manual_seed(0)
    data = DPPatchDataset(discover_dp_dataset(tiny_synthetic_dataset, "train"),
                          PatchConfig(patch_size=32, frames=2, flips=False))
    items = [data[(i, i)] for i in range(2)]
    batch = {k: torch.stack([it[k] for it in items]) for k in items[0]}
    # The residual variant: the paper's 3-channel ReLU head, built without the trainer's
    # centring on a first batch, gets stuck for some seeds (measured: 2 of 4 seeds fell < 5x in
    # 250 steps), which would make this test depend on the seed.
    model = build_model("rdpd", width=0.25, lstm_dropout=0.0, residual=True)
    frames = model.spec.make_input(batch["left"], batch["right"], batch["radial"])
    optimizer = torch.optim.Adam(model.parameters(), lr=2e-3)
    criterion = DeblurLoss()
    losses = []
    for _ in range(200):
        loss, _ = criterion(model(frames)[0], batch["target"])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    # It starts at the identity (the blurred input) and must learn the sharpening: measured
    # 5.5-5.9x lower after 200 steps over four seeds.
    assert min(losses[-10:]) < losses[0] / 4


@pytest.mark.parametrize(("ema_decay", "model"), [(0.0, "rdpd"), (0.9, "rdpd"), (0.9, "dpnaf")])
def test_resume_continues_exactly(tiny_synthetic_dataset, tmp_path, ema_decay, model):
    config = tiny_config(tiny_synthetic_dataset, lr_halve_every=1, val_data=str(
        tiny_synthetic_dataset), val_split="train", val_limit=1, ema_decay=ema_decay,
        model=model, residual=model == "dpnaf")
    straight = train(config, tmp_path / "straight", progress=False)
    first = train(tiny_config(tiny_synthetic_dataset, lr_halve_every=1, epochs=1,
                              val_data=str(tiny_synthetic_dataset), val_split="train",
                              val_limit=1, ema_decay=ema_decay, model=model,
                              residual=model == "dpnaf"), tmp_path / "resumed",
                  progress=False)
    assert first.step == 3
    resumed = train(config, tmp_path / "resumed", resume=True, progress=False)
    assert resumed.step == straight.step == 6
    # Same learning rate schedule and the same weights as the uninterrupted run.
    assert [r["learning_rate"] for r in resumed.history] == [1e-3, 5e-4]
    assert resumed.history == [
        {**r, "seconds": s["seconds"]} for r, s in zip(straight.history, resumed.history)
    ]
    a = load_model(tmp_path / "straight" / "last.safetensors").state_dict()
    b = load_model(tmp_path / "resumed" / "last.safetensors").state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)
    assert (tmp_path / "resumed" / "best.safetensors").is_file()
    lines = (tmp_path / "resumed" / "history.jsonl").read_text().splitlines()
    assert [json.loads(line)["epoch"] for line in lines] == [1, 2]


def test_run_moved_with_its_data_resumes_and_other_data_is_refused(tiny_synthetic_dataset,
                                                                    tmp_path):
    """A run folder moved (or copied) together with its data resumes under the new paths; data
    elsewhere under the same settings is refused by name."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_synthetic_dataset, run / "data")
    settings = dict(val_split="train", val_limit=1)
    train(tiny_config(run / "data", epochs=1, val_data=str(run / "data"), **settings),
          run / "phase", progress=False)
    moved = tmp_path / "moved"
    shutil.move(run, moved)
    resumed = train(tiny_config(moved / "data", val_data=str(moved / "data"), **settings),
                    moved / "phase", resume=True, progress=False)
    assert resumed.step == 6 and [r["epoch"] for r in resumed.history] == [1, 2]
    saved = yaml.safe_load((moved / "phase" / "config.yaml").read_text())
    assert saved["synthetic_data"] == str(moved / "data")
    recorded = json.loads((moved / "phase" / "paths.json").read_text())
    assert recorded["val_data"] == [[str((moved / "data").resolve()), "../data"]]

    shutil.copytree(tiny_synthetic_dataset, tmp_path / "other")
    with pytest.raises(ParameterError, match="synthetic_data"):
        train(tiny_config(tmp_path / "other", epochs=3, val_data=str(moved / "data"),
                          **settings), moved / "phase", resume=True, progress=False)


def test_cosine_schedule_decays_over_the_run_and_resumes(tiny_synthetic_dataset, tmp_path):
    config = tiny_config(tiny_synthetic_dataset, epochs=4, iterations_per_epoch=1,
                         lr_schedule="cosine")
    straight = train(config, tmp_path / "straight", progress=False)
    # lr_e = lr * (1 + cos(pi e / 4)) / 2 for epochs e = 0..3.
    expected = [1e-3, 1e-3 * (1 + 2**-0.5) / 2, 5e-4, 1e-3 * (1 - 2**-0.5) / 2]
    assert [r["learning_rate"] for r in straight.history] == pytest.approx(expected)
    train(tiny_config(tiny_synthetic_dataset, epochs=2, iterations_per_epoch=1,
                      lr_schedule="cosine"), tmp_path / "resumed", progress=False)
    resumed = train(config, tmp_path / "resumed", resume=True, progress=False)
    # Lengthened on resume: the later epochs follow the 4-epoch curve.
    assert [r["learning_rate"] for r in resumed.history[2:]] == pytest.approx(expected[2:])
    with pytest.raises(ParameterError, match="lr_schedule"):
        tiny_config(tiny_synthetic_dataset, lr_schedule="linear")


def test_charbonnier_pixel_term_trains_otherwise_and_is_checked(tiny_synthetic_dataset,
                                                                tmp_path):
    runs = {pixel: train(tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=2,
                                     pixel_loss=pixel), tmp_path / pixel, progress=False)
            for pixel in ("mse", "charbonnier")}
    weights = {pixel: load_model(tmp_path / pixel / "last.safetensors").state_dict()
               for pixel in runs}
    assert any(not torch.equal(weights["mse"][k], weights["charbonnier"][k])
               for k in weights["mse"])
    assert all(math.isfinite(r["loss"]) for run in runs.values() for r in run.history)
    with pytest.raises(ParameterError, match="pixel_loss"):
        tiny_config(tiny_synthetic_dataset, pixel_loss="l1")


def _largest_steps(start, run) -> dict[str, float]:
    """The largest change of each of a few weight tensors from ``start`` to ``run``'s last
    weights (the first Adam step's size is the rate, whatever the gradient)."""
    moved = load_model(run / "last.safetensors").state_dict()
    names = ("bottleneck.0.weight", "upconvs.0.conv.weight", "encoders.0.0.weight",
             "decoders.0.0.weight", "refiner.head.weight")
    return {k: (moved[k] - v).abs().max().item() for k, v in start.state_dict().items()
            if k in names}


def test_coarsest_level_learns_at_its_own_rate(tiny_synthetic_dataset, tmp_path):
    """coarsest_lr_scale: two Adam groups on one schedule; the coarsest level's weights move
    `scale` times as far in the first Adam step (whose size is the rate, whatever the gradient);
    a resume keeps both rates on the curve."""
    from dualpixel.models import save_model
    from dualpixel.training.trainer import Trainer

    torch.manual_seed(5)
    start = build_model("rdpd", width=0.125, lstm_dropout=0.0)
    save_model(tmp_path / "start.safetensors", start)
    config = tiny_config(tiny_synthetic_dataset, epochs=2, iterations_per_epoch=1,
                         lr_schedule="cosine", coarsest_lr_scale=4.0, lstm_dropout=0.0,
                         init_weights=str(tmp_path / "start.safetensors"))
    trainer = Trainer(config, tmp_path / "run", progress=False)
    trainer.run()
    groups = trainer.optimizer.param_groups
    assert [g["initial_lr"] for g in groups] == [1e-3, 4e-3]
    coarse = {id(p) for m in trainer.net.coarsest_level() for p in m.parameters()}
    assert {id(p) for p in groups[1]["params"]} == coarse
    assert len(groups[0]["params"]) + len(coarse) == len(list(trainer.net.parameters()))

    one = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1,
                      lr_schedule="cosine", coarsest_lr_scale=4.0, lstm_dropout=0.0,
                      init_weights=str(tmp_path / "start.safetensors"))
    train(one, tmp_path / "one", progress=False)
    # Adam's first step moves every weight with a gradient by the rate (1e-3 or 4e-3).
    assert _largest_steps(start, tmp_path / "one") == pytest.approx(
        {"bottleneck.0.weight": 4e-3, "upconvs.0.conv.weight": 4e-3,
         "encoders.0.0.weight": 1e-3, "decoders.0.0.weight": 1e-3}, rel=1e-3)

    resumed = train(config, tmp_path / "one", resume=True, progress=False)
    straight = json.loads((tmp_path / "run" / "history.jsonl").read_text().splitlines()[1])
    assert resumed.history[1]["loss"] == pytest.approx(straight["loss"], rel=1e-6)
    with pytest.raises(ParameterError, match="coarsest_lr_scale must be > 0"):
        load_config(None, {"synthetic_data": "x", "coarsest_lr_scale": 0})


def test_base_learns_at_its_own_rate_beside_the_refiner(tiny_synthetic_dataset,
                                                               tmp_path):
    """base_lr_scale: the base network of a refined network in an Adam group of its own;
    Adam's first step moves a weight by its group's rate, and with coarsest_lr_scale too the
    coarsest level gets both multiples."""
    from dualpixel.models import save_model
    from dualpixel.training.trainer import Trainer

    torch.manual_seed(6)
    start = build_model("rdpd", width=0.125, residual=True, lstm_dropout=0.0, refiner=(8, 16))
    with torch.no_grad():  # a residual head starts at zero: no gradient below it in step one
        start.head[-1].weight.normal_(std=0.01)
    save_model(tmp_path / "start.safetensors", start)
    config = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1,
                         residual=True, lstm_dropout=0.0, refiner=[8, 16],
                         base_lr_scale=0.25, coarsest_lr_scale=2.0,
                         init_weights=str(tmp_path / "start.safetensors"))
    trainer = Trainer(config, tmp_path / "run", progress=False)
    trainer.run()
    assert [g["initial_lr"] for g in trainer.optimizer.param_groups] == [1e-3, 2.5e-4, 5e-4]
    # The refiner's head starts at zero, so in the first step only it has a gradient there.
    # (Adam's first step is rate * g / (|g| + eps): a hair short of the rate for tiny g.)
    assert _largest_steps(start, tmp_path / "run") == pytest.approx(
        {"refiner.head.weight": 1e-3, "encoders.0.0.weight": 2.5e-4,
         "decoders.0.0.weight": 2.5e-4, "bottleneck.0.weight": 5e-4,
         "upconvs.0.conv.weight": 5e-4}, rel=5e-2)
    for wrong in ({"base_lr_scale": 0.5},  # no refiner
                  {"base_lr_scale": 0.5, "refiner": [8], "freeze_base": True}):
        with pytest.raises(ParameterError, match="base_lr_scale needs a refiner"):
            load_config(None, {"synthetic_data": "x", **wrong})
    with pytest.raises(ParameterError, match="base_lr_scale must be > 0"):
        load_config(None, {"synthetic_data": "x", "refiner": [8], "base_lr_scale": 0})


def test_weight_average_is_what_a_run_saves(tiny_synthetic_dataset, tmp_path):
    """With ema_decay, last.safetensors holds the moving average (kept in last_state.pt beside
    the raw weights), and the average lags the weights as the warm-up formula says."""
    from dualpixel.training.trainer import _ema_update

    train(tiny_config(tiny_synthetic_dataset, epochs=1, ema_decay=0.99), tmp_path / "run",
          progress=False)
    state = torch.load(tmp_path / "run" / "last_state.pt", weights_only=False)
    saved = load_model(tmp_path / "run" / "last.safetensors").state_dict()
    raw, average = state["model"], state["ema"]
    assert int(average["n_averaged"]) == 3  # one update per iteration
    moved = [k for k in saved if not torch.equal(saved[k], raw[k])]
    assert moved  # three Adam steps at 1e-3: the average differs from the weights
    for key in saved:
        torch.testing.assert_close(saved[key], average[f"module.{key}"], rtol=0, atol=0)
    # The update: the first average is the weights; then d = min(decay, (1 + n) / (10 + n)).
    avg, new = [torch.zeros(3), torch.tensor([4])], [torch.ones(3), torch.tensor([7])]
    _ema_update(0.99)(avg, new, torch.tensor(1))
    torch.testing.assert_close(avg[0], torch.full((3,), 1 - 2 / 11))
    assert avg[1].item() == 7  # integer buffers are copied
    _ema_update(0.99)(avg, [torch.zeros(3), new[1]], torch.tensor(10_000))
    torch.testing.assert_close(avg[0], torch.full((3,), (1 - 2 / 11) * 0.99))


def test_reinit_bottleneck_applies_to_the_initial_weights(tiny_synthetic_dataset, tmp_path):
    from dualpixel.models import save_model

    torch.manual_seed(3)
    start = build_model("rdpd", width=0.125)
    save_model(tmp_path / "start.safetensors", start)
    train(tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1,
                      learning_rate=1e-12, init_weights=str(tmp_path / "start.safetensors"),
                      reinit_bottleneck=True), tmp_path / "run", progress=False)
    after = load_model(tmp_path / "run" / "last.safetensors").state_dict()
    before = start.state_dict()
    half = start.shape.encoder[-1]
    assert after["decoders.0.0.weight"][:, half:].abs().max() < 1e-9  # cut (one 1e-12 step)
    torch.testing.assert_close(after["decoders.0.0.weight"][:, :half],
                               before["decoders.0.0.weight"][:, :half])
    assert not torch.allclose(after["bottleneck.0.weight"], before["bottleneck.0.weight"])
    torch.testing.assert_close(after["encoders.3.0.weight"], before["encoders.3.0.weight"])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_run_from_nothing_starts_with_its_heads_relu_alive(tiny_synthetic_dataset, tmp_path,
                                                             seed):
    """DPDNet from nothing: the head's three channels are positive on part of the training
    crops after the first step (centred on the first batch), whatever the seed; a run from
    given weights keeps their bias."""
    from dualpixel.data import DPPatchDataset, PatchConfig, discover_dp_dataset
    from dualpixel.models import save_model

    config = tiny_config(tiny_synthetic_dataset, model="dpdnet", epochs=1,
                         iterations_per_epoch=1, learning_rate=1e-12, seed=seed)
    train(config, tmp_path / "run", progress=False)
    data = DPPatchDataset(discover_dp_dataset(tiny_synthetic_dataset, "train"),
                          PatchConfig(patch_size=64, frames=1, flips=False))
    items = [data[(i, 0)] for i in range(4)]
    frames = torch.cat([torch.cat([it["left"], it["right"]], 1) for it in items])
    model = load_model(tmp_path / "run" / "last.safetensors")
    seen = []
    model.head[0].register_forward_hook(lambda m, a, out: seen.append(out.clone()))
    with torch.no_grad():
        model.eval().step(frames)
    assert min(float((seen[0][:, c] > 0).float().mean()) for c in range(3)) > 0.05
    save_model(tmp_path / "start.safetensors", model)
    train(tiny_config(tiny_synthetic_dataset, model="dpdnet", epochs=1, iterations_per_epoch=1,
                      learning_rate=1e-12, init_weights=str(tmp_path / "start.safetensors")),
          tmp_path / "again", progress=False)
    torch.testing.assert_close(load_model(tmp_path / "again" / "last.safetensors").head[0].bias,
                               model.head[0].bias)


def test_a_run_without_the_head_relu_trains_that_head(tiny_synthetic_dataset, tmp_path):
    """``head_relu: false`` trains DPDNet's head without its ReLU (nothing to centre), and the
    run's file rebuilds it so; the option is refused where no head has a ReLU."""
    torch.manual_seed(0)
    config = tiny_config(tiny_synthetic_dataset, model="dpdnet", epochs=1,
                         iterations_per_epoch=2, head_relu=False)
    train(config, tmp_path / "run", progress=False)
    model = load_model(tmp_path / "run" / "last.safetensors")
    assert not model.head_has_relu and isinstance(model.head[1], torch.nn.Identity)
    assert load_config(tmp_path / "run" / "config.yaml").head_relu is False
    for options in ({"residual": True}, {"model": "dpnaf"}):
        with pytest.raises(ParameterError, match="head_relu false is for the non-residual"):
            load_config(None, {"synthetic_data": "x", "head_relu": False, **options})


def test_a_run_with_a_conv_bottleneck_trains_rdpd_without_state(tiny_synthetic_dataset,
                                                                 tmp_path):
    """``conv_bottleneck: true`` trains RDPD with DPDNet's bottleneck on sequences (no state to
    carry, so not temporal); the run's file rebuilds it so; DPDNet refuses the option."""
    torch.manual_seed(0)
    config = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=2,
                         synthetic_as_frames=False, conv_bottleneck=True)
    train(config, tmp_path / "run", progress=False)
    model = load_model(tmp_path / "run" / "last.safetensors")
    assert model.conv_bottleneck and model.lstm is None and not model.temporal
    assert load_config(tmp_path / "run" / "config.yaml").conv_bottleneck is True
    with pytest.raises(ParameterError, match="no ConvLSTM to replace"):
        load_config(None, {"synthetic_data": "x", "model": "dpdnet", "conv_bottleneck": True})
    with pytest.raises(ParameterError, match="encoder_dropout"):
        load_config(None, {"synthetic_data": "x", "encoder_dropout": 1.0})


def test_balance_levels_scales_the_up_convolutions_of_a_run_from_nothing(
        tiny_synthetic_dataset, tmp_path):
    """``balance_levels: true`` rescales each up-convolution on the first batch of a run from
    nothing (the same seed without it differs by those factors only); it is refused with
    init_weights and for NAF levels."""
    runs = {}
    for balance in (False, True):
        torch.manual_seed(0)
        config = tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1,
                             learning_rate=1e-12, ema_decay=0.0, head_relu=False,
                             balance_levels=balance)
        train(config, tmp_path / f"run-{balance}", progress=False)
        runs[balance] = load_model(tmp_path / f"run-{balance}" / "last.safetensors")
    assert load_config(tmp_path / "run-True" / "config.yaml").balance_levels is True
    ratios = [float(b.conv.weight.detach().norm() / a.conv.weight.detach().norm())
              for a, b in zip(runs[False].upconvs, runs[True].upconvs)]
    assert all(abs(r - 1) > 1e-3 for r in ratios) and ratios[0] > 1.5, ratios
    for (key, a), b in zip(runs[False].state_dict().items(), runs[True].state_dict().values()):
        if not key.startswith("upconvs."):
            torch.testing.assert_close(a, b, msg=key)
    with pytest.raises(ParameterError, match="balance_levels is for a run from nothing"):
        load_config(None, {"synthetic_data": "x", "balance_levels": True, "init_weights": "w"})
    with pytest.raises(ParameterError, match="balance_levels is for the paper's convolution"):
        load_config(None, {"synthetic_data": "x", "balance_levels": True, "model": "dpnaf"})


def test_a_dead_head_is_reported_in_the_history_and_a_warning(tiny_synthetic_dataset,
                                                                tmp_path):
    """Each epoch of a ReLU-head network records the share of training pixels each head channel
    passes; a channel under 1 % is named in a warning (it no longer learns). Heads without that
    ReLU record nothing."""
    from dualpixel.models import save_model

    torch.manual_seed(0)
    start = build_model("dpdnet", width=0.125)
    with torch.no_grad():
        start.head[0].bias.copy_(torch.tensor([-1e3, 0.0, 0.0]))  # channel 0 dead
    save_model(tmp_path / "start.safetensors", start)
    trainer = Trainer(tiny_config(tiny_synthetic_dataset, model="dpdnet", epochs=1,
                                  iterations_per_epoch=2, learning_rate=1e-12,
                                  init_weights=str(tmp_path / "start.safetensors")),
                      tmp_path / "run", progress=False)
    with pytest.warns(UserWarning, match=r"epoch 1: the head's ReLU passed channel\(s\) 0 on"):
        result = trainer.run()
    live = result.history[0]["head_live"]
    assert live[0] == 0.0 and min(live[1:]) > 0.01, live
    history = (tmp_path / "run" / "history.jsonl").read_text()
    assert '"head_live"' in history
    assert not trainer.net.head[0]._forward_hooks  # the hook went with the epoch
    linear = train(tiny_config(tiny_synthetic_dataset, model="dpdnet", epochs=1,
                               iterations_per_epoch=1, head_relu=False),
                   tmp_path / "linear", progress=False)
    assert "head_live" not in linear.history[0]


def test_widen_init_starts_from_the_narrow_networks_function(tiny_synthetic_dataset, tmp_path):
    from dualpixel.models import save_model

    torch.manual_seed(5)
    start = build_model("rdpd", width=0.125, residual=True)
    with torch.no_grad():
        start.head[-1].weight.normal_(0, 0.1)  # a correction to keep (it starts at zero)
    save_model(tmp_path / "start.safetensors", start)
    train(tiny_config(tiny_synthetic_dataset, epochs=1, iterations_per_epoch=1, residual=True,
                      width=0.25, learning_rate=1e-12, widen_init=True,
                      init_weights=str(tmp_path / "start.safetensors")),
          tmp_path / "run", progress=False)
    after = load_model(tmp_path / "run" / "last.safetensors")
    assert after.shape.encoder == tuple(2 * w for w in start.shape.encoder)
    frames = torch.rand(1, 1, 7, 32, 48)
    with torch.no_grad():
        torch.testing.assert_close(after.eval()(frames)[0], start.eval()(frames)[0],
                                   rtol=0, atol=1e-4)
    with pytest.raises(ParameterError, match="widen_init needs init_weights"):
        load_config(None, {"synthetic_data": "x", "widen_init": True})


def test_refiner_trains_on_top_of_a_frozen_base(tiny_synthetic_dataset, tmp_path):
    from dualpixel.models import save_model

    torch.manual_seed(4)
    start = build_model("rdpd", width=0.125, residual=True)
    save_model(tmp_path / "start.safetensors", start)
    train(tiny_config(tiny_synthetic_dataset, epochs=1, residual=True, refiner=[8, 16],
                      freeze_base=True, init_weights=str(tmp_path / "start.safetensors")),
          tmp_path / "run", progress=False)
    after = load_model(tmp_path / "run" / "last.safetensors")
    assert after.shape.refiner == (8, 16)
    state = after.state_dict()
    for key, value in start.state_dict().items():  # the base network stayed as it was
        torch.testing.assert_close(state[key], value, rtol=0, atol=0)
    assert state["refiner.head.weight"].abs().max() > 0  # the refiner learned (it starts at 0)
    # The starting checkpoint renamed since (a new default shipped): the run still resumes, from
    # its own state; only the first epoch read init_weights.
    (tmp_path / "start.safetensors").rename(tmp_path / "renamed.safetensors")
    resumed = train(tiny_config(tiny_synthetic_dataset, epochs=2, residual=True, refiner=[8, 16],
                                freeze_base=True,
                                init_weights=str(tmp_path / "renamed.safetensors")),
                    tmp_path / "run", resume=True, progress=False)
    assert [r["epoch"] for r in resumed.history] == [1, 2]
    # The run folder records the length it now has and the weights it started from.
    saved = load_config(tmp_path / "run" / "config.yaml")
    assert (saved.epochs, saved.init_weights) == (2, str(tmp_path / "start.safetensors"))
    with pytest.raises(ParameterError, match="freeze_base needs a refiner"):
        load_config(None, {"synthetic_data": "x", "freeze_base": True})
    with pytest.raises(ParameterError, match="refiner must list channel widths"):
        load_config(None, {"synthetic_data": "x", "refiner": [0]})


def test_refusals(tiny_synthetic_dataset, tmp_path):
    train(tiny_config(tiny_synthetic_dataset, epochs=1), tmp_path / "run", progress=False)
    with pytest.raises(ParameterError, match="--resume"):
        train(tiny_config(tiny_synthetic_dataset, epochs=1), tmp_path / "run", progress=False)
    with pytest.raises(ParameterError, match="differs from the saved run in learning_rate"):
        train(tiny_config(tiny_synthetic_dataset, learning_rate=1.0), tmp_path / "run",
              resume=True, progress=False)
    with pytest.raises(InputFileError, match=r"nothing to resume.*without --resume"):
        train(tiny_config(tiny_synthetic_dataset), tmp_path / "new", resume=True, progress=False)
    with pytest.raises(ParameterError, match=r"unknown config key.*learnin_rate"):
        load_config(None, {"learnin_rate": 1})
    with pytest.raises(ParameterError, match="epochs"):
        load_config(None, {"epochs": "many", "synthetic_data": "x"})
    with pytest.raises(ParameterError, match=r"ema_decay must be in \[0, 1\), got 1.0"):
        load_config(None, {"synthetic_data": "x", "ema_decay": 1.0})
    with pytest.raises(ParameterError, match="differs from the saved run in ema_decay"):
        train(tiny_config(tiny_synthetic_dataset, ema_decay=0.9), tmp_path / "run",
              resume=True, progress=False)
    with pytest.raises(ParameterError, match="reinit_bottleneck needs init_weights"):
        load_config(None, {"synthetic_data": "x", "reinit_bottleneck": True})
    with pytest.raises(ParameterError, match="real_data, synthetic_data"):
        load_config(None, {})
    # --set val_data=null switches an optional path off (it is no file named "null")
    assert load_config(None, {"synthetic_data": "x", "val_data": "null"}).val_data is None
    assert load_config(None, {"synthetic_data": "x", "val_data": "null.d"}).val_data == "null.d"


def test_alternates_real_and_synthetic(tiny_synthetic_dataset, tmp_path):
    real = tmp_path / "real"
    write_dpdd_pairs(real, "train", ["a", "b", "c"], size=(40, 48))
    config = tiny_config(tiny_synthetic_dataset, real_data=str(real), real_batch=2, epochs=1,
                         iterations_per_epoch=None)
    result = train(config, tmp_path / "mixed", progress=False)
    # default epoch: both kinds, one pass over the larger (4 sequences / batch 2, 3 pairs / 2)
    assert result.step == 4


def test_train_command_end_to_end(tiny_synthetic_dataset, tmp_path):
    config_file = tmp_path / "c.yaml"
    config_file.write_text(yaml.safe_dump({
        "model": "rdpd", "width": 0.125, "synthetic_data": str(tiny_synthetic_dataset),
        "val_data": str(tiny_synthetic_dataset), "val_split": "train", "val_limit": 1,
        "patch_size": 32, "sequence_frames": 2, "epochs": 1, "iterations_per_epoch": 2,
        "workers": 1,
    }))
    out = tmp_path / "run"
    result = CliRunner().invoke(cli, ["train", "--config", str(config_file), "--set",
                                      "epochs=2", "--output", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "trained 4 steps" in result.output
    # Without bars, each epoch still leaves its record in the log.
    records = [json.loads(line) for line in result.output.splitlines() if line.startswith("{")]
    assert [r["epoch"] for r in records] == [1, 2] and "val_psnr" in records[-1]
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert saved["epochs"] == 2 and saved["width"] == 0.125
    assert load_model(out / "best.safetensors").spec.name == "rdpd"
    assert list((out / "tensorboard").iterdir())  # TensorBoard event files
    bad = CliRunner().invoke(cli, ["train", "--config", str(config_file), "--set", "nope=1",
                                   "--output", str(tmp_path / "x")])
    assert bad.exit_code == 2 and "unknown config key" in bad.output


def test_models_command_lists_counts():
    result = CliRunner().invoke(cli, ["models"])
    assert result.exit_code == 0
    assert "24,278,703" in result.output and "31,035,151" in result.output
    from dualpixel.models import ARCHITECTURES, build_architecture, count_parameters

    for name in ARCHITECTURES:  # every name `architecture:` takes, with what it builds
        count = count_parameters(build_architecture(name))
        assert re.search(rf"^  {re.escape(name)}: .*{count:,} parameters$", result.output,
                         flags=re.M)
    # the shipped checkpoints with their metadata
    from dualpixel.weights import model_info

    for name, info in model_info().items():
        aliases = f" (alias {', '.join(info['aliases'])})" if info["aliases"] else ""
        if "preset_of" in info:  # a preset: shipped weights with settings of its own
            aliases = f" (preset: {info['preset_of']} with its own settings)"
        assert f"{name}{aliases}: {info['description']}" in result.output
        assert info["sha256"][:16] in result.output
        assert f"recipes/{info['recipe']} phase {info['phase']}" in result.output
        block = re.search(rf"^  {re.escape(name)}\b.*?(?=^  \S|\Z)", result.output,
                          flags=re.S | re.M).group()  # this model's lines
        fused = info["output"]["fuse_frames"]
        frames = (f"each frame fused with up to {fused - 1} earlier" if fused > 1
                  else "carries its state" if info["temporal"] else "single frames")
        assert frames in block, block
        for dataset, scores in info["metrics"].items():
            assert f"{dataset}: {scores['psnr']:.2f} dB" in result.output


@pytest.mark.parametrize("as_frames", [False, True])
def test_torchrun_two_processes(tiny_synthetic_dataset, tmp_path, as_frames):
    """Multi-process training through torchrun (gloo on the CPU), as on a multi-GPU machine;
    single frames (sRDPD+) leave the recurrent convolution unused, which DDP must accept."""
    import os
    import subprocess
    import sys

    out = tmp_path / "ddp"
    command = [
        sys.executable, "-m", "torch.distributed.run", "--nproc-per-node", "2",
        "--standalone", "-m", "dualpixel", "train", "--output", str(out),
        "--no-progress", "--set", f"synthetic_data={tiny_synthetic_dataset}",
        "--set", "width=0.125", "--set", "patch_size=32", "--set", "sequence_frames=2",
        "--set", "epochs=1", "--set", "iterations_per_epoch=2", "--set", "workers=0",
        "--set", "tensorboard=false", "--set", "threads=1",
        "--set", f"synthetic_as_frames={str(as_frames).lower()}",
        "--set", "device=cpu",  # two processes on gloo also where one GPU is present
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert load_model(out / "last.safetensors").spec.name == "rdpd"
    history = [json.loads(line) for line in (out / "history.jsonl").read_text().splitlines()]
    assert history[-1]["step"] == 2


@pytest.mark.parametrize(("key", "value", "message"), [
    ("learning_rate", ".inf", "learning_rate must be finite"),
    ("learning_rate", ".nan", "learning_rate must be finite"),
    ("iterations_per_epoch", "0", "iterations_per_epoch must be between 1 and"),
    ("val_limit", "0", "val_limit must be between 1 and"),
    ("lambda_x", "-0.1", "lambda_x"),
    ("lstm_dropout", "5", "lstm_dropout"),
    ("workers", "-1", "workers must be between 0 and"),
    ("threads", "0", "threads must be between 1 and"),
    ("width", "0", "width must be > 0"),
])
def test_config_values_are_checked_up_front(tiny_synthetic_dataset, key, value, message):
    """Issue #34: values that would train to NaN, do nothing, or crash later are refused by
    name before any work."""
    with pytest.raises(ParameterError, match=message):
        load_config(None, {"synthetic_data": str(tiny_synthetic_dataset), key: value})


def test_old_key_names_read_as_the_new_ones(tmp_path):
    """freeze_first_stage / first_stage_lr_scale (configs written before the rename) still load."""
    (tmp_path / "old.yaml").write_text("synthetic_data: d\nrefiner: [8]\n"
                                       "first_stage_lr_scale: 0.5\n")
    assert load_config(tmp_path / "old.yaml").base_lr_scale == 0.5
    assert load_config(None, {"synthetic_data": "d", "refiner": "[8]",
                              "freeze_first_stage": "true"}).freeze_base
    with pytest.raises(ParameterError, match="old name of base_lr_scale"):
        load_config(None, {"synthetic_data": "d", "refiner": "[8]",
                           "first_stage_lr_scale": "0.5", "base_lr_scale": "0.5"})


@pytest.mark.parametrize("memory", [torch.channels_last, torch.contiguous_format])
def test_validation_keeps_the_training_memory_format(tiny_synthetic_dataset, memory):
    """Validation runs through inference (which converts the model to channels-last): training
    continues in the layout it had, or a resumed run would not continue exactly (channels-last
    training used to fall back to contiguous after the first validation)."""
    from dualpixel.data.layout import discover_dp_dataset
    from dualpixel.training.trainer import validate

    model = build_model("rdpd", width=0.125).to(memory_format=memory).train()
    sequences = discover_dp_dataset(tiny_synthetic_dataset, "train")[:1]
    score, _ = validate(model, sequences, torch.device("cpu"))
    assert score == score and model.training  # a number (not NaN), back in training mode
    weight = next(p for p in model.parameters() if p.ndim == 4 and p.shape[-1] > 1)
    assert weight.is_contiguous(memory_format=memory)


@pytest.mark.parametrize("native_bf16", [True, False])
@pytest.mark.parametrize("channels_last", [True, False])
def test_training_lays_weights_out_as_configured_on_any_cpu(tiny_synthetic_dataset, tmp_path,
                                                            monkeypatch, native_bf16,
                                                            channels_last):
    """Channels-last is a layout, not a precision: a CPU without native bfloat16 trains in
    float32 and still channels-last (1.44x faster a step, ``bench_training.py``), unless
    ``channels_last: false``; bfloat16 autocast follows the CPU."""
    from dualpixel.training import trainer as trainer_module

    monkeypatch.setattr(trainer_module, "cpu_has_native_bf16", lambda: native_bf16)
    run = trainer_module.Trainer(tiny_config(tiny_synthetic_dataset, device="cpu",
                                             channels_last=channels_last), tmp_path / "run")
    run.check_folder()
    run.build()
    weight = next(p for p in run.net.parameters() if p.ndim == 4 and p.shape[-1] > 1)
    memory = torch.channels_last if channels_last else torch.contiguous_format
    assert weight.is_contiguous(memory_format=memory)
    assert not weight.is_contiguous(memory_format=torch.channels_last if not channels_last
                                    else torch.contiguous_format)
    assert trainer_module.fast_numerics(torch.device("cpu")) is native_bf16


def test_the_fused_optimiser_takes_the_steps_of_the_loop():
    from dualpixel.training.config import TrainConfig
    from dualpixel.training.trainer import make_optimizer

    torch.manual_seed(0)
    nets = [build_model("rdpd", width=0.125, residual=True, refiner=[4, 8], lstm_dropout=0.0)
            for _ in range(2)]
    nets[1].load_state_dict(nets[0].state_dict())
    config = TrainConfig(synthetic_data="unused", refiner=[4, 8], learning_rate=1e-3)
    fused = make_optimizer(nets[0], config, torch.device("cpu"))
    loop = torch.optim.Adam(_groups_of(fused, nets[0], nets[1]), lr=config.learning_rate,
                            foreach=False)
    assert fused.defaults["fused"] is True
    x = torch.rand(1, 2, 7, 32, 32)
    for _ in range(3):
        for net, optimizer in zip(nets, (fused, loop), strict=True):
            optimizer.zero_grad()
            net(x)[0].square().mean().backward()
            optimizer.step()
    for a, b in zip(nets[0].parameters(), nets[1].parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)


def _groups_of(optimizer, source, target):
    """``optimizer``'s parameter groups of ``source``, mapped onto ``target``'s parameters."""
    index = {id(p): k for k, p in enumerate(source.parameters())}
    params = list(target.parameters())
    return [{k: v for k, v in g.items() if k not in ("params", "fused", "foreach")}
            | {"params": [params[index[id(p)]] for p in g["params"]]}
            for g in optimizer.param_groups]


def test_a_runs_thread_count_does_not_outlive_it(tiny_synthetic_dataset, tmp_path):
    before = torch.get_num_threads()
    other = 1 if before != 1 else 2
    train(tiny_config(tiny_synthetic_dataset, epochs=1, threads=other), tmp_path / "run",
          progress=False)
    assert torch.get_num_threads() == before


def test_the_progress_bar_shows_a_log_loss_in_decibels():
    """Issue #73: with loss_reduction "log" the bar showed ``loss=-20.22``, a negative error."""
    from dualpixel.training.trainer import _shown_loss

    assert _shown_loss(-20.2187, "log") == "-20.22 dB"
    assert _shown_loss(0.012345, "mean") == "0.01235"
