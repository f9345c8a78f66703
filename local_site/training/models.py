"""The three networks of the comparison (thesis ch. 4-5), widths scaled for CPU.

All take one preprocessed depth crop, [B, 1, 96, 96] in [-1, 1], and end in fractions of
each joint's range mapped onto the Shadow joint limits (clamped to them outside
training), so the exported ONNX graph returns radians within the limits.
"""

import torch
from torch import nn
import torch.nn.functional as F

SIZE = 96


def conv_bn(cin, cout, stride):
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride, 1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


# Training on CPUs with bfloat16 units (AVX512-BF16, AMX) runs the convolutions in
# bfloat16, about twice as fast; the fully connected layers, the losses and the
# exported graph stay float32, so the regression keeps its precision.
CONV_BF16 = False


def conv_forward(net, x):
    if CONV_BF16:
        with torch.autocast("cpu", dtype=torch.bfloat16):
            return net(x.contiguous(memory_format=torch.channels_last)).float()
    return net(x)


class Encoder(nn.Module):
    """Six 3x3 conv layers, 96 x 96 -> 6 x 6 x C (Transteleop's encoder shape). The
    first one already strides: full-resolution layers dominate CPU time."""

    def __init__(self, widths):
        super().__init__()
        c1, c2, c3, c4, c5 = widths
        self.net = nn.Sequential(
            conv_bn(1, c1, 2),  # 48
            conv_bn(c1, c2, 2),  # 24
            conv_bn(c2, c3, 1),  # 24
            conv_bn(c3, c4, 2),  # 12
            conv_bn(c4, c5, 2),  # 6
            conv_bn(c5, c5, 1),  # 6
        )
        self.channels = c5

    def forward(self, x):
        return conv_forward(self.net, x).flatten(1)


class LimitMap(nn.Module):
    """The head's outputs, as fractions of each joint's range, mapped onto
    [lower, upper] (rad). Linear while training; clamped to [0, 1] (the limits) in
    evaluation and in the exported graph. A sigmoid would need infinite logits for the
    many labels that sit at a joint limit (a fingertip joint straight, the thumb fully
    flexed: 10-45 % of labels for some joints) and would learn them slowly and never
    exactly; the clamp makes them exact."""

    def __init__(self, lower, upper):
        super().__init__()
        self.register_buffer("lower", torch.tensor(lower, dtype=torch.float32))
        self.register_buffer("span", torch.tensor(upper, dtype=torch.float32) - self.lower)

    def forward(self, x):
        x = x + 0.5  # an untrained head starts mid-range
        if not self.training:
            x = x.clamp(0.0, 1.0)
        return self.lower + x * self.span


def mlp(sizes, last_relu=False):
    layers = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2 or last_relu:
            layers.append(nn.ReLU(inplace=True))
    return nn.Sequential(*layers)


class Baseline(nn.Module):
    """Single branch: human image -> encoder -> embedding -> 3 FC layers -> joints."""

    kind = "baseline"

    def __init__(self, lower, upper, widths, embed=512):
        super().__init__()
        self.encoder = Encoder(widths)
        self.embed = mlp([36 * self.encoder.channels, embed], last_relu=True)
        self.head = mlp([embed, 256, 128, len(lower)])
        self.limits = LimitMap(lower, upper)

    def forward(self, human):
        return self.limits(self.head(self.embed(self.encoder(human))))

    def losses(self, batch):
        q = self(batch["human"])
        return {"joint": F.mse_loss(q, batch["joints"])}, q


class _Branch(nn.Module):
    def __init__(self, widths, embed, n):
        super().__init__()
        self.encoder = Encoder(widths)
        self.embed = mlp([36 * self.encoder.channels, embed], last_relu=True)
        self.penultimate = mlp([embed, 256], last_relu=True)
        self.out = nn.Linear(256, n)

    def forward(self, x):
        z = self.penultimate(self.embed(self.encoder(x)))
        return z, self.out(z)


class TeachNet(nn.Module):
    """Teacher (robot image) and student (human image) branches; the "hard-late"
    consistency loss aligns the student's penultimate features with the teacher's
    (eqs. 4.2-4.5, alpha = 1). Only the student runs at inference."""

    kind = "teachnet"

    def __init__(self, lower, upper, widths, embed=512, alpha=1.0):
        super().__init__()
        self.student = _Branch(widths, embed, len(lower))
        self.teacher = _Branch(widths, embed, len(lower))
        self.limits = LimitMap(lower, upper)
        self.alpha = alpha

    def forward(self, human):
        return self.limits(self.student(human)[1])

    def losses(self, batch):
        zh, qh = self.student(batch["human"])
        zr, qr = self.teacher(batch["robot"])
        qh, qr = self.limits(qh), self.limits(qr)
        return {
            "joint": F.mse_loss(qh, batch["joints"]),
            "teacher": F.mse_loss(qr, batch["joints"]),
            "align": self.alpha * F.mse_loss(zh, zr.detach()),
        }, qh


def up(cin, cout):
    return nn.Sequential(
        nn.ConvTranspose2d(cin, cout, 4, 2, 1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


class Transteleop(nn.Module):
    """Encoder 96 x 96 -> 6 x 6 x C, two FC layers to the pose embedding Z_pose, an FC
    layer to Z_R, a decoder of 4 up-convolutions reconstructing the robot's depth
    image; the joint module (3 FC layers) regresses joints from the embedding.
    Loss = 1 x keypoint-weighted reconstruction L2 (eqs. 5.2-5.3) + 10 x joint MSE."""

    kind = "transteleop"

    def __init__(self, lower, upper, widths, embed=512, lambda_recon=1.0, lambda_joint=10.0):
        super().__init__()
        self.encoder = Encoder(widths)
        c = self.encoder.channels
        self.pose = mlp([36 * c, embed, embed], last_relu=True)
        self.to_robot = mlp([embed, 36 * c], last_relu=True)
        c1, c2, c3, c4, _ = widths
        self.decoder = nn.Sequential(
            up(c, c4),  # 12
            up(c4, c3),  # 24
            up(c3, c2),  # 48
            nn.ConvTranspose2d(c2, 1, 4, 2, 1),  # 96
            nn.Tanh(),
        )
        self.joint_module = mlp([embed, 256, 128, len(lower)])
        self.limits = LimitMap(lower, upper)
        self.lambda_recon = lambda_recon
        self.lambda_joint = lambda_joint
        self.c = c

    def forward(self, human):
        return self.limits(self.joint_module(self.pose(self.encoder(human))))

    def losses(self, batch):
        z = self.pose(self.encoder(batch["human"]))
        q = self.limits(self.joint_module(z))
        recon = conv_forward(self.decoder, self.to_robot(z).view(-1, self.c, 6, 6))
        w = batch["recon_weight"]
        l_recon = (w * (recon - batch["robot"]) ** 2).mean()
        return {
            "joint": self.lambda_joint * F.mse_loss(q, batch["joints"]),
            "recon": self.lambda_recon * l_recon,
        }, q


MODELS = {m.kind: m for m in (Baseline, TeachNet, Transteleop)}
