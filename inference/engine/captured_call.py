"""Static-shape calls for the GPU path: a function run on fixed input buffers, captured once as a CUDA graph and
replayed, so a frame costs one graph launch instead of hundreds of kernel launches from Python.

The same code runs everywhere: inputs are copied into the static buffers and the function reads only those.
On a CUDA device the call is captured (after warm-up on a side stream) and replayed; on the CPU, or when
capture fails (an operation that cannot be captured, out of memory), it is called eagerly on the same buffers
and `mode` says why. A captured graph's outputs live in its own memory and are overwritten by the next
replay: callers copy what they keep (`CapturedCall.__call__` returns clones).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager

import torch

WARMUP_CALLS = 3
"""Eager calls on a side stream before capture (cuBLAS / cuDNN workspaces, lazy initialisation)."""
MAX_GRAPHS = 64
"""Distinct input shapes captured per runtime; calls of further shapes run eagerly (bounded GPU memory)."""


def eager_reason(device: torch.device, capture: bool) -> str:
    """Why calls on `device` run eagerly ("eager (…)"), or "" when they are captured."""
    if device.type != "cuda":
        return "eager (CUDA graphs need a CUDA GPU)"
    return "" if capture else "eager (capture off)"


class CapturedCall:
    """`fn(*inputs) -> Tensor` on static input buffers shaped like `example`; `mode` is "CUDA graph" or
    "eager (<why>)". `context` (autocast, say) is entered around warm-up, capture and eager calls; `capture`
    False never captures."""

    def __init__(self, fn: Callable[..., torch.Tensor], example: Sequence[torch.Tensor],
                 context: Callable[[], AbstractContextManager], capture: bool = True) -> None:
        self.fn, self.context = fn, context
        self.inputs = [x.detach().clone() for x in example]
        self.graph: torch.cuda.CUDAGraph | None = None
        self.output: torch.Tensor | None = None
        device = self.inputs[0].device
        self.mode = eager_reason(device, capture) or self._capture()

    def _capture(self) -> str:
        try:
            stream = torch.cuda.Stream(self.inputs[0].device)
            stream.wait_stream(torch.cuda.current_stream(self.inputs[0].device))
            with torch.cuda.stream(stream), self.context():
                for _ in range(WARMUP_CALLS):
                    self.fn(*self.inputs)
            torch.cuda.current_stream(self.inputs[0].device).wait_stream(stream)
            graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(graph), self.context():
                self.output = self.fn(*self.inputs)
        except (RuntimeError, torch.cuda.OutOfMemoryError) as exc:
            self.graph, self.output = None, None
            return f"eager (capture failed: {str(exc).splitlines()[0][:120]})"
        self.graph = graph
        return "CUDA graph"

    def __call__(self, *inputs: torch.Tensor) -> torch.Tensor:
        for buffer, value in zip(self.inputs, inputs):
            buffer.copy_(value, non_blocking=True)
        if self.graph is None:
            with self.context():
                return self.fn(*self.inputs)
        self.graph.replay()
        return self.output.clone()


class CapturedCalls:
    """One `CapturedCall` per distinct input shapes (and dtypes) of `fn`, up to MAX_GRAPHS; `mode` summarises
    them ("CUDA graphs", "eager (…)")."""

    def __init__(self, fn: Callable[..., torch.Tensor], context: Callable[[], AbstractContextManager],
                 capture: bool = True) -> None:
        self.fn, self.context, self.capture = fn, context, capture
        self.calls: dict[tuple, CapturedCall] = {}
        self.eager_beyond_limit = 0

    def __call__(self, *inputs: torch.Tensor) -> torch.Tensor:
        key = tuple((tuple(x.shape), x.dtype) for x in inputs)
        call = self.calls.get(key)
        if call is None:
            if len(self.calls) >= MAX_GRAPHS:
                self.eager_beyond_limit += 1
                with self.context():
                    return self.fn(*inputs)
            call = self.calls[key] = CapturedCall(self.fn, inputs, self.context, self.capture)
        return call(*inputs)

    def expected_mode(self, device: torch.device) -> str:
        """What the calls on `device` will be before any has run."""
        return eager_reason(device, self.capture) or "CUDA graphs (captured at the first call)"

    @property
    def mode(self) -> str:
        modes = sorted({call.mode for call in self.calls.values()})
        if not modes:
            return "not run yet"
        return "CUDA graphs" if modes == ["CUDA graph"] else "; ".join(modes)
