"""Where the model runs: the `--device` setting (auto, cpu, cuda, cuda:N), the precisions a device offers, and
the process group of a `torchrun` launch. torch is imported where it is used: `touchanything --help` loads this
module."""
from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

from touchanything.core.errors import UserError

if TYPE_CHECKING:
    import torch

DEVICE_HELP = "auto (the first CUDA GPU when there is one, else the CPU), cpu, cuda or cuda:N"
PRECISIONS = {"fp32": None, "bf16": "bfloat16", "fp16": "float16", "tf32": None}
"""Precision name → the name of its autocast dtype in torch (None: no autocast). tf32 keeps fp32 weights and
activations and lets a CUDA GPU's matrix products and convolutions run in TensorFloat-32 (`autocast`)."""


def resolve_device(name: str, local_rank: int = 0) -> torch.device:
    """`auto` → cuda:`local_rank` when CUDA is available, else cpu; `cpu`; `cuda` (= cuda:`local_rank`) or
    `cuda:N`. One UserError line for a malformed name, CUDA asked for but absent, or N out of range."""
    import torch

    if not isinstance(name, str):
        raise UserError(f"device must be text ({DEVICE_HELP}), got {name!r}")
    if name == "auto":
        return torch.device(f"cuda:{local_rank}") if torch.cuda.is_available() else torch.device("cpu")
    if name == "cpu":
        return torch.device("cpu")
    match = re.fullmatch(r"cuda(?::(\d+))?", name)
    if match is None:
        raise UserError(f"unknown device {name!r}; choose {DEVICE_HELP}")
    if not torch.cuda.is_available():
        raise UserError(f"device {name!r} asked for, but this machine has no usable CUDA GPU (torch "
                        f"{torch.__version__}); use --device cpu or auto")
    index = int(match.group(1)) if match.group(1) is not None else local_rank
    if index >= torch.cuda.device_count():
        raise UserError(f"device {name!r}: there are only {torch.cuda.device_count()} CUDA GPU(s) (cuda:0 … "
                        f"cuda:{torch.cuda.device_count() - 1})")
    return torch.device(f"cuda:{index}")


GPU_PRECISIONS = ("fp16", "tf32")
"""Precisions a CUDA GPU offers and a CPU does not."""
NVIDIA_DEVICE_FILES = ("/dev/nvidiactl", "/dev/dxg")
"""Device files one of which a CUDA GPU needs (Linux; WSL): without them CUDA cannot be there."""


def check_precision(precision: str, device: torch.device) -> None:
    """UserError for an unknown precision, or fp16 or tf32 on the CPU."""
    if precision not in PRECISIONS:
        raise UserError(f"unknown precision {precision!r}; choose from {', '.join(PRECISIONS)}")
    if precision in GPU_PRECISIONS and device.type == "cpu":
        raise UserError(f"{precision} needs a CUDA GPU (--device cuda); on the CPU use fp32 or bf16")


def check_precision_early(precision: str, device: str) -> None:
    """`check_precision` where it needs no torch (a one-line error then comes before torch loads, seconds
    sooner): a GPU precision on `--device cpu`, or on `auto` where no NVIDIA device file exists."""
    no_gpu = device == "cpu" or (device == "auto" and not any(map(os.path.exists, NVIDIA_DEVICE_FILES)))
    if precision in GPU_PRECISIONS and no_gpu:
        raise UserError(f"{precision} needs a CUDA GPU (--device cuda); on the CPU use fp32 or bf16")


def device_label(device: torch.device) -> str:
    """`cpu` or `cuda:0 (NVIDIA H100 80GB HBM3)`: what the dashboard, summaries and bench rows show."""
    import torch

    if device.type != "cuda":
        return device.type
    return f"{device} ({torch.cuda.get_device_name(device)})"


@contextmanager
def autocast(device: torch.device, precision: str) -> Iterator[None]:
    """The context of `precision` on `device`: autocast for bf16 / fp16 (a no-op for fp32), and for tf32 the
    CUDA matrix products and cuDNN convolutions in TensorFloat-32 (`matmul_precision`). Autocast's weight-cast
    cache is off: a CUDA graph captured under autocast would otherwise point at cached casts freed when the
    context exits (each call enters a fresh context, so the cache would not outlive a call anyway)."""
    import torch

    dtype = getattr(torch, PRECISIONS[precision]) if PRECISIONS[precision] else None
    with matmul_precision("tf32" if precision == "tf32" else None), \
            torch.autocast(device.type, dtype=dtype, enabled=dtype is not None, cache_enabled=False):
        yield


@contextmanager
def matmul_precision(mode: str | None) -> Iterator[None]:
    """CUDA's fp32 matrix-product and convolution precision set to `mode` ("tf32", "ieee") inside the context
    and restored after, also on an exception (None: left alone). The setting is process-wide; on a CPU it
    changes nothing the CPU computes."""
    if mode is None:
        yield
        return
    import torch

    settings = (torch.backends.cuda.matmul, torch.backends.cudnn.conv)
    before = [s.fp32_precision for s in settings]
    try:
        for s in settings:
            s.fp32_precision = mode
        yield
    finally:
        for s, value in zip(settings, before):
            s.fp32_precision = value


@dataclass(frozen=True)
class ProcessGroup:
    """rank / world size / local rank of this process; world 1 outside `torchrun`."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def join_process_group(device_name: str = "auto") -> ProcessGroup:
    """Under `torchrun` (WORLD_SIZE > 1) initialise the process group once — NCCL when this process runs on
    a CUDA GPU (made the current device), else gloo — and return where this process stands."""
    import torch
    import torch.distributed as dist

    world = int(os.environ.get("WORLD_SIZE", "1"))
    local = int(os.environ.get("LOCAL_RANK", "0"))
    if world > 1 and not dist.is_initialized():
        device = resolve_device(device_name, local)
        if device.type == "cuda":
            torch.cuda.set_device(device)  # NCCL's collectives (all_gather_object too) use the current device
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
    return ProcessGroup(dist.get_rank() if world > 1 else 0, world, local)
