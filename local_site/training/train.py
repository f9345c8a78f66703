"""Train one hand network on a dataset made by `hand_dataset`, export it to ONNX.

    python train.py --model transteleop --train DATA/train --val DATA/val \
        --minutes 30 --out runs/transteleop

Writes to --out: `model.onnx` (input `depth` [batch, 1, 96, 96] float32 in [-1, 1],
output `joints` [batch, 17] float32 radians, Shadow joint order; metadata records the
joint names and limits, the preprocessing and the dataset), `checkpoint.pt`,
`log.json` (per-epoch losses and validation metrics).

The thesis recipe is the starting point: Adam lr 0.002, betas (0.5, 0.999), learning
rate halved on a schedule (here at 60, 80 and 95 % of the time budget, since the run is
time-boxed rather than 80-epoch-boxed), random in-plane rotation and pixel jitter.
"""

import argparse
import json
import math
import os
import time

import numpy as np
import torch
import torch.nn.functional as F

import models
from models import MODELS, SIZE

# BigHand indices of the 15 keypoints whose neighbourhoods weight the reconstruction
# loss (PIP, DIP, TIP of every finger, thumb first).
RECON_KEYPOINTS = list(range(6, 21))


def load(root):
    with open(os.path.join(root, "manifest.json")) as f:
        manifest = json.load(f)
    parts = {k: [] for k in ("human", "robot", "joints", "robot_uv", "meta")}
    for shard in manifest["shards"]:
        for k in parts:
            parts[k].append(np.load(os.path.join(root, shard["dir"], k + ".npy")))
    data = {k: np.concatenate(v) for k, v in parts.items()}
    return manifest, data


def cpu_has_bf16():
    """True on x86 CPUs that report AVX512-BF16 or AMX-BF16 (Linux /proc/cpuinfo)."""
    try:
        with open("/proc/cpuinfo") as f:
            flags = f.read()
    except OSError:
        return False
    return "avx512_bf16" in flags or "amx_bf16" in flags


def augment(batch, rng, rotate_deg, jitter_px, images=("human", "robot")):
    """Same random in-plane rotation and shift for the human image, the robot image and
    the robot keypoints of each sample. Nearest sampling, background padded with +1."""
    b = batch["human"].shape[0]
    angle = torch.from_numpy(rng.uniform(-rotate_deg, rotate_deg, b).astype(np.float32)) * math.pi / 180
    shift = torch.from_numpy(rng.uniform(-jitter_px, jitter_px, (b, 2)).astype(np.float32)) * 2 / SIZE
    cos, sin = torch.cos(angle), torch.sin(angle)
    # affine_grid maps output coordinates to input coordinates: in = A out + t.
    a = torch.stack([torch.stack([cos, -sin], 1), torch.stack([sin, cos], 1)], 1)
    theta = torch.cat([a, shift[:, :, None]], 2)
    grid = F.affine_grid(theta, (b, 1, SIZE, SIZE), align_corners=False)
    out = dict(batch)
    for k in images:
        out[k] = F.grid_sample(batch[k] - 1, grid, mode="nearest", padding_mode="zeros", align_corners=False) + 1
    # Keypoints: out = A^-1 (in - t), in normalised coordinates.
    uv = batch["robot_uv"]
    p = (2 * uv + 1) / SIZE - 1
    p = torch.einsum("bji,bkj->bki", a, p - shift[:, None, :])  # A^T = A^-1 for rotations
    out["robot_uv"] = ((p + 1) * SIZE - 1) / 2
    return out


def recon_weight(uv):
    """Per-pixel weights of eqs. 5.2-5.3: 1 everywhere, plus 10 (1 - D / D_max) on each
    keypoint's pixel and its 8 neighbours (D = distance from the pixel centre to the
    keypoint, D_max = 2 px), summed over the 15 keypoints."""
    b = uv.shape[0]
    kp = uv[:, RECON_KEYPOINTS, :]  # [B, 15, 2]
    base = kp.round()
    w = torch.ones(b, SIZE * SIZE)
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            pix = base + torch.tensor([du, dv], dtype=kp.dtype)
            dist = (pix - kp).norm(dim=-1)
            alpha = (1 - dist / 2.0).clamp(min=0)
            inside = ((pix >= 0) & (pix < SIZE)).all(-1)
            index = (pix[..., 1].clamp(0, SIZE - 1) * SIZE + pix[..., 0].clamp(0, SIZE - 1)).long()
            w.scatter_add_(1, index, 10 * alpha * inside)
    return w.view(b, 1, SIZE, SIZE)


def to_batch(data, idx, device="cpu"):
    return {
        "human": torch.from_numpy(data["human"][idx].astype(np.float32))[:, None],
        "robot": torch.from_numpy(data["robot"][idx].astype(np.float32))[:, None],
        "joints": torch.from_numpy(data["joints"][idx]),
        "robot_uv": torch.from_numpy(data["robot_uv"][idx]),
    }


@torch.no_grad()
def evaluate(model, data, batch_size=256):
    model.eval()
    bf16, models.CONV_BF16 = models.CONV_BF16, False  # measured as exported: float32
    errs = []
    for s in range(0, len(data["joints"]), batch_size):
        idx = np.arange(s, min(s + batch_size, len(data["joints"])))
        b = to_batch(data, idx)
        errs.append((model(b["human"]) - b["joints"]).abs())
    e = torch.cat(errs)
    worst = e.amax(1)
    models.CONV_BF16 = bf16
    model.train()
    return {
        "mean_error_rad": float(e.mean()),
        "frac_max_le_0.1": float((worst <= 0.1).float().mean()),
        "frac_max_le_0.2": float((worst <= 0.2).float().mean()),
    }


class Exported(torch.nn.Module):
    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, depth):
        return self.model(depth)


def export(model, path, manifest, args, metrics):
    import onnx

    model.eval()
    models.CONV_BF16 = False  # the exported graph is float32 throughout
    model = model.to(memory_format=torch.contiguous_format)
    dummy = torch.zeros(1, 1, SIZE, SIZE)
    torch.onnx.export(
        Exported(model),
        (dummy,),
        path,
        input_names=["depth"],
        output_names=["joints"],
        dynamic_axes={"depth": {0: "batch"}, "joints": {0: "batch"}},
        opset_version=17,
        dynamo=False,
    )
    m = onnx.load(path)
    meta = {
        "teleop.model": model.kind,
        "teleop.input": f"depth: float32 [batch, 1, {SIZE}, {SIZE}], preprocessed depth in [-1, 1]",
        "teleop.output": "joints: float32 [batch, 17], radians, joint_names order",
        "teleop.joint_names": ",".join(manifest["joint_names"]),
        "teleop.joint_lower": ",".join(f"{v:.9g}" for v in manifest["joint_lower"]),
        "teleop.joint_upper": ",".join(f"{v:.9g}" for v in manifest["joint_upper"]),
        "teleop.cube_mm": str(manifest["cube_mm"]),
        "teleop.image_size": str(manifest["image_size"]),
        "teleop.dataset": f"{manifest['generator']} v{manifest['generator_version']} seed {manifest['config']['seed']} count {manifest['config']['count']}",
        "teleop.training": json.dumps({k: v for k, v in vars(args).items()}),
        "teleop.validation": json.dumps(metrics),
    }
    del m.metadata_props[:]
    for k, v in meta.items():
        p = m.metadata_props.add()
        p.key, p.value = k, v
    onnx.checker.check_model(m)
    onnx.save(m, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", choices=sorted(MODELS), required=True)
    ap.add_argument("--train", required=True)
    ap.add_argument("--val", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--minutes", type=float, default=30.0, help="training time budget")
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--lr", type=float, default=0.002)
    ap.add_argument("--beta1", type=float, default=0.5)
    ap.add_argument("--widths", default="24,48,64,128,160", help="encoder widths (5 values)")
    ap.add_argument("--embed", type=int, default=256)
    ap.add_argument("--rotate-deg", type=float, default=15.0)
    ap.add_argument("--jitter-px", type=float, default=4.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument(
        "--bf16",
        choices=("auto", "on", "off"),
        default="auto",
        help="convolutions in bfloat16 while training (auto: when the CPU has bfloat16 units)",
    )
    args = ap.parse_args()

    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    os.makedirs(args.out, exist_ok=True)
    manifest, train = load(args.train)
    _, val = load(args.val)
    widths = [int(w) for w in args.widths.split(",")]
    models.CONV_BF16 = args.bf16 == "on" or (args.bf16 == "auto" and cpu_has_bf16())
    model = MODELS[args.model](manifest["joint_lower"], manifest["joint_upper"], widths, embed=args.embed)
    if models.CONV_BF16:
        model = model.to(memory_format=torch.channels_last)
    # The baseline sees only the human image; the others also learn from the robot's.
    images = ("human",) if args.model == "baseline" else ("human", "robot")
    params = sum(p.numel() for p in model.parameters())
    print(
        f"{args.model}: {params / 1e6:.2f} M parameters, {len(train['joints'])} training pairs, "
        f"convolutions in {'bfloat16' if models.CONV_BF16 else 'float32'}",
        flush=True,
    )
    opt = torch.optim.Adam(model.parameters(), lr=args.lr, betas=(args.beta1, 0.999))
    budget = args.minutes * 60
    start = time.monotonic()
    n = len(train["joints"])
    log = {"args": vars(args), "parameters": params, "epochs": []}
    best = None
    epoch = 0
    done = False
    halvings = 0
    while not done:
        epoch += 1
        order = rng.permutation(n)
        sums, count, seen = {}, 0, 0
        for s in range(0, n - args.batch + 1, args.batch):
            elapsed = time.monotonic() - start
            if elapsed > budget:
                done = True
                break
            # Halve the learning rate at 60, 80 and 95 % of the budget.
            want = sum(elapsed > f * budget for f in (0.6, 0.8, 0.95))
            while halvings < want:
                halvings += 1
                for g in opt.param_groups:
                    g["lr"] *= 0.5
            batch = augment(to_batch(train, order[s : s + args.batch]), rng, args.rotate_deg, args.jitter_px, images)
            if args.model == "transteleop":
                batch["recon_weight"] = recon_weight(batch["robot_uv"])
            losses, _ = model.losses(batch)
            loss = sum(losses.values())
            opt.zero_grad()
            loss.backward()
            opt.step()
            for k, v in losses.items():
                sums[k] = sums.get(k, 0.0) + float(v.detach())
            count += 1
            seen += args.batch
        if count == 0:
            break
        metrics = evaluate(model, val)
        entry = {
            "epoch": epoch,
            "samples": seen,
            "minutes": (time.monotonic() - start) / 60,
            "lr": opt.param_groups[0]["lr"],
            "losses": {k: v / count for k, v in sums.items()},
            "val": metrics,
        }
        log["epochs"].append(entry)
        print(json.dumps(entry), flush=True)
        key = (metrics["frac_max_le_0.1"], -metrics["mean_error_rad"])
        if best is None or key > best[0]:
            best = (key, {k: v.clone() for k, v in model.state_dict().items()}, metrics, epoch)
    model.load_state_dict(best[1])
    log["best_epoch"] = best[3]
    log["best_val"] = best[2]
    torch.save(best[1], os.path.join(args.out, "checkpoint.pt"))
    export(model, os.path.join(args.out, "model.onnx"), manifest, args, best[2])
    with open(os.path.join(args.out, "log.json"), "w") as f:
        json.dump(log, f, indent=1)
    print(f"best epoch {best[3]}: {best[2]}; wrote {args.out}/model.onnx", flush=True)


if __name__ == "__main__":
    main()
