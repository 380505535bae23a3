"""The mutants of `benchmarks/mutation.py` that cannot be killed: each survivor judged equivalent, keyed by the
mutated module and the mutant's changed line (stripped), with the reason. If the line changes, the entry no longer
applies and the mutant shows up again as a survivor."""
from __future__ import annotations

_M = "inference/evaluation/metrics.py"
_S = "inference/engine/streaming_engine.py"
EQUIVALENT: dict[tuple[str, str], str] = {
    (_M, "flat = (grids.shape[0], valid[ -1].size if grids.shape[0] else 0)"):
        "every frame has the same shape: the last frame's size is the first's",
    (_M, "flat = (grids.shape[0], valid[0].size if grids.shape[0] else 1)"):
        "with no frame the array is empty and reshapes to (0, 0) and to (0, 1) alike; the sums are empty either way",
    (_M, "above = (valid & (np.nan_to_num(grids, nan= 1.0) > threshold)).reshape(flat).sum(axis=1)"):
        "a NaN cell is not `valid`, so the value it is replaced by is masked out by `valid &`",
    (_M, "if gt.shape[ -1] == 0:"):
        "the early return for an empty chunk only saves work: without it an empty chunk adds 0 to every sum and a "
        "(2, 0) flag array, the same result (a grid's last axis is 21, never 0)",
    (_M, "above = (valid & (np.nan_to_num(grids, nan= -1.0) > threshold)).reshape(flat).sum(axis=1)"):
        "a NaN cell is not `valid`, so the value it is replaced by is masked out by `valid &`",
    (_M, 'return dict.fromkeys(DETECTION_METRICS[: 4], float("nan")) | {"temporal_support": 0}'):
        "the fourth key, temporal_support, is set to 0 by the `| {...}` that follows either way",
    (_M, 'return dict.fromkeys(EVENT_METRICS[: 5], float("nan")) | {"num_gt_onsets": 0, "num_gt_offsets": 0}'):
        "the fifth key, num_gt_onsets, is set to 0 by the `| {...}` that follows either way",
    (_M, "p_flags, g_flags = np.concatenate(self.kept_flags, axis=1) if self.kept_flags else np.zeros((2, 1), bool)"):
        "with no kept frame the event metrics see one frame instead of none: fewer than two either way, so NaN "
        "ratios and zero counts; the other metrics do not read the flags",
    (_M, "if gt.shape[ 1] == 0:"):
        "axis 1 is the two hands, never 0, so the early return is skipped for an empty chunk: it only saves work "
        "(an empty chunk adds 0 to every sum and a (2, 0) flag array)",
    ("devices/tactile_layout.py", "out = np.asarray(raw, dtype=np.float32)[..., np.where(valid, self.sensor_index[hand], -1)]"):
        "the slot read for a cell outside the layout is a placeholder: the next line sets those cells to NaN",
    ("devices/tactile_layout.py", "out = np.asarray(raw, dtype=np.float32)[..., np.where(valid, self.sensor_index[hand], 1)]"):
        "the slot read for a cell outside the layout is a placeholder: the next line sets those cells to NaN",
    ("devices/tactile_layout.py", "values = grid[..., h, :, :][..., cells].reshape(- 2, slots.size)"):
        "numpy (2.4) takes any negative size as the one to infer, so reshape(-2, n) is reshape(-1, n)",
    (_S, "if window is None and self.config.output == \"newest\":"):
        "with the newest output every cached frame was emitted by the step that cached it, so the centre branch "
        "that follows finds nothing left to drain; with no window nothing is cached and the stitch is empty",
    (_S, 'status = "ok" if not missing else ("no valid hand pose" if len(missing) == 2 else f"{missing[ -1]} hand: no pose")'):
        "that branch is taken when exactly one hand is missing: its first name is its last",
    ("inference/evaluation/evaluation.py", "has = ~np.all(np.isnan(prediction.reshape(len(prediction), - 2)), axis=1)"):
        "numpy (2.4) takes any negative size as the one to infer, so reshape(n, -2) is reshape(n, -1)",
    ("devices/output_safety.py", "names = [*Path(out).parts[ 0 if Path(out).is_absolute() else 0:], temporary_path(out).name]"):
        "the extra part is the root \"/\", one byte: never the name over the limit",
    ("devices/output_safety.py", "path.unlink(missing_ok=False)"):
        "`_remove` runs under contextlib.suppress(OSError): a missing file is ignored either way",
    ("devices/output_safety.py", "os.kill(pid, -1)"):
        "−1 is not a signal: the kernel answers ESRCH (ProcessLookupError: not running) for a process that has ended "
        "and EINVAL (another OSError: running) for one that runs, the answers signal 0 gives",
    (_S, "prediction = Prediction(frame_index=frame.frame_index, t_us=frame.t_us, pressure=pressure - self.mask,"):
        "the mask is 0 inside the layout and NaN outside, so subtracting it gives what adding it gives (the pressures "
        "are ≥ 0: no −0)",
    (_S, "self._emitted = - 2"):
        "frame indices count from 0 (an episode frame or the rig's tick counter), so −1 and −2 both mean "
        "\"nothing emitted yet\" to every comparison with a frame index",
    (_S, "self._emitted, self._count, self._last = - 2, 0, None"):
        "frame indices count from 0 (an episode frame or the rig's tick counter), so −1 and −2 both mean "
        "\"nothing emitted yet\" to every comparison with a frame index",
    (_M, "if gt.shape[0] == -1:"):
        "the early return for an empty chunk only saves work: without it an empty chunk adds 0 to every sum and a "
        "(2, 0) flag array, the same result",
    ("viz/frame_facts.py", "return np.array([contact_frames(np.asarray(grids[h])[None, None], bend[h][None], threshold)[ -1] "
                           "for h in range(2)])"):
        "`contact_frames` is given one frame (`[None, None]`), so its flags have length 1 and [-1] is [0]",
}
"""(module path, the mutant's changed line stripped) → why that mutant cannot change what the module does."""
