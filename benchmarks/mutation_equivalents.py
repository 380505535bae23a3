"""The mutants of `benchmarks/mutation.py` that cannot be killed: each survivor judged equivalent, keyed by the
mutated module and the mutant's changed line (stripped), with the reason. If the line changes, the entry no longer
applies and the mutant shows up again as a survivor."""
from __future__ import annotations

_M = "inference/evaluation/metrics.py"
_S = "inference/engine/streaming_engine.py"
_W = "devices/episodes/lerobot_writer.py"
_R = "devices/episodes/lerobot_episode.py"
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
    ("core/tactile_layout.py", "out = np.asarray(raw, dtype=np.float32)[..., np.where(valid, self.sensor_index[hand], -1)]"):
        "the slot read for a cell outside the layout is a placeholder: the next line sets those cells to NaN",
    ("core/tactile_layout.py", "out = np.asarray(raw, dtype=np.float32)[..., np.where(valid, self.sensor_index[hand], 1)]"):
        "the slot read for a cell outside the layout is a placeholder: the next line sets those cells to NaN",
    ("core/tactile_layout.py", "values = grid[..., h, :, :][..., cells].reshape(- 2, slots.size)"):
        "numpy (2.4) takes any negative size as the one to infer, so reshape(-2, n) is reshape(-1, n)",
    (_S, "if window is None and self.config.output == \"newest\":"):
        "with the newest output every cached frame was emitted by the step that cached it, so the centre branch "
        "that follows finds nothing left to drain; with no window nothing is cached and the stitch is empty",
    (_S, 'status = "ok" if not missing else ("no valid hand pose" if len(missing) == 2 else f"{missing[ -1]} hand: no pose")'):
        "that branch is taken when exactly one hand is missing: its first name is its last",
    ("inference/evaluation/evaluation.py", "has = ~np.all(np.isnan(prediction.reshape(len(prediction), - 2)), axis=1)"):
        "numpy (2.4) takes any negative size as the one to infer, so reshape(n, -2) is reshape(n, -1)",
    ("core/output_safety.py", "names = [*Path(out).parts[ 0 if Path(out).is_absolute() else 0:], temporary_path(out).name]"):
        "the extra part is the root \"/\", one byte: never the name over the limit",
    ("core/output_safety.py", "path.unlink(missing_ok=False)"):
        "`_remove` runs under contextlib.suppress(OSError): a missing file is ignored either way",
    ("core/output_safety.py", "os.kill(pid, -1)"):
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
    **{(_W, line): why for line, why in (
        ("VIDEO_CRF = 21", "a quality setting (x264's constant rate factor), not a behaviour: crf 19, 20 or 21 give the same "
                           "frames within the codec's error, the same times and the same metadata"),
        ("VIDEO_CRF = 19", "a quality setting (x264's constant rate factor), not a behaviour: crf 19, 20 or 21 give the same "
                           "frames within the codec's error, the same times and the same metadata"),
        ("fmt.TRACKERS: poses.reshape(t, - 2), fmt.TRACKERS_VALID: trackers_valid.astype(np.float32),",
         "numpy (2.4) takes any negative size as the one to infer, so reshape(t, -2) is reshape(t, -1)"),
        ("flat = pa.array(values.reshape(- 2))", "numpy (2.4) takes any negative size as the one to infer"),
        ("return {fmt.STATE: np.concatenate([joints.reshape(t, - 2), seen.astype(np.float32)], axis=1),",
         "numpy (2.4) takes any negative size as the one to infer"),
        ("meta.mkdir(parents=False, exist_ok=True)", "meta/'s parent is the writer's folder, which exists (export_lerobot "
                                                     "creates it before the writer), so no parent is ever made"),
        ('return {"feature": {"dtype": dtype, "_type": "Value"}, "length": shape[ -1], "_type": "List"}',
         "the branch is for a 1-D shape, whose first size is its last"),
        ("if values.ndim == 0:", "a 1-D column then skips both branches and the loop over `values.shape[1:]` (empty), "
                                 "returning the same flat array"),
        ("count = len(flat) / size", "len(flat) is a multiple of size, so the float quotient is the integer one and "
                                     "np.arange(count + 1, dtype=np.int32) the same offsets"),
        ("if self._data_writer.file_handle is not None and self._data_writer.file_handle.tell() > fmt.DATA_FILE_MB * 1000001.0:",
         "the limit moves by 100 bytes in LeRobot's 100 MB; files are closed after a whole episode, never at a byte"),
        ("if self._data_writer.file_handle is not None and self._data_writer.file_handle.tell() > fmt.DATA_FILE_MB * 999999.0:",
         "the limit moves by 100 bytes in LeRobot's 100 MB; files are closed after a whole episode, never at a byte"),
        ("if self._data_writer.file_handle is not None and self._data_writer.file_handle.tell() >= fmt.DATA_FILE_MB * 1e6:",
         "a data file of exactly 100 000 000 bytes after an episode: the limit differs by one byte"),
        ("if writer.path.exists() and writer.path.stat().st_size >= fmt.VIDEO_FILE_MB * 1e6:",
         "a video file of exactly 200 000 000 bytes after an episode: the limit differs by one byte"),
        ("if writer.path.exists() and writer.path.stat().st_size > fmt.VIDEO_FILE_MB * 1000001.0:",
         "the limit moves by 200 bytes in LeRobot's 200 MB; files are closed after a whole episode, never at a byte"),
        ("if writer.path.exists() and writer.path.stat().st_size > fmt.VIDEO_FILE_MB * 999999.0:",
         "the limit moves by 200 bytes in LeRobot's 200 MB; files are closed after a whole episode, never at a byte"),
        ("meta.mkdir(parents=True, exist_ok=False)", "the writer's folder is new (export_lerobot gives it an empty temporary "
                                                     "folder) and nothing before `close` makes meta/"),
        ("path.parent.mkdir(parents=True, exist_ok=False)", "this line also stands for the episodes metadata's folder, new "
                                                            "at `close`; the data and video folders' mutants are killed by "
                                                            "the export whose files close after every episode"),
        ("stats = {key: aggregate([s[key] for s in self._stats]) for key in self._stats[ -1]} if self._stats else {}",
         "every episode has the same features, so the last one's keys are the first one's"),
        ("(self.folder / fmt.STATS_PATH).write_text(json.dumps(as_json(stats), indent= 2))", "JSON layout only"),
        ("(self.folder / fmt.STATS_PATH).write_text(json.dumps(as_json(stats), indent= 0))", "JSON layout only"),
        ("(self.folder / fmt.INFO_PATH).write_text(json.dumps(self.info(), indent= 0))", "JSON layout only"),
        ("(self.folder / fmt.INFO_PATH).write_text(json.dumps(self.info(), indent= 2))", "JSON layout only"),
    )},
    **{(_R, line): why for line, why in (
        ("joints = state[:, :fmt.JOINT_VALUES].reshape(- 2, 2, 21, 3).astype(np.float32)",
         "numpy (2.4) takes any negative size as the one to infer"),
        ("poses, valid = poses.reshape(- 2, 3, 7).astype(np.float32), _flags(table, fmt.TRACKERS_VALID, 3)",
         "numpy (2.4) takes any negative size as the one to infer"),
        ("values = _array(table, key, (len(cells[ 1]),)) if cells is not None else None",
         "hand, row and column index arrays of the cells have one length"),
        ("values = _array(table, key, (len(cells[ -1]),)) if cells is not None else None",
         "hand, row and column index arrays of the cells have one length"),
        ('return {index: {"episode_index": index} for index in range(int(info.get("total_episodes", -1)))}',
         "range(-1) is as empty as range(0)"),
        ('view = fmt.VIEW_ALIASES.get(key.rsplit(".", 2)[-1])', "the last part of the name is the same however many "
                                                                "splits are made from the right"),
        ("valid = hands_valid(joints) & np.any(joints != 0, axis=(-1, +2)) if valid is None else valid",
         "joints are (frames, 2, 21, 3): axis 2 is axis −2"),
        ("seen = state[:, fmt.JOINT_VALUES:] >= 0.5", "this project's export writes the seen flags as 0.0 or 1.0 "
                                                      "(`frame_features`): no value lies at 0.5"),
        ("except (CosmicRayTestingException, pa.ArrowException) as exc:", "not killable as root: pyarrow raises its read errors as "
         "ArrowException (caught either way) or FileNotFoundError (caught by the clause before); a plain OSError from "
         "pq.read_table needs e.g. a permission denied, which root never gets"),
    )},
    **{("devices/episodes/lerobot_stats.py", line): why for line, why in (
        ("batch = rows.astype(np.result_type(rows.dtype, np.float32), copy=True)", "a copy changes no value"),
        ('QUANTILE_KEYS = tuple(f"q{int(q * 101):02d}" for q in QUANTILES)',
         "int() truncates 1.01, 10.1, 50.5, 90.9 and 99.99 to the same key names"),
        ("if inside == -1:", "LeRobot's guard is never true: searchsorted gives the first bin whose cumulative count "
                             "reaches the target, above the one before, so that bin holds a value"),
        ("rows = values.reshape(- 2, 1) if values.ndim == 1 else values.reshape(-1, values.shape[-1])",
         "numpy (2.4) takes any negative size as the one to infer"),
        ("rows = values.reshape(-1, 1) if values.ndim == 1 else values.reshape(- 2, values.shape[-1])",
         "numpy (2.4) takes any negative size as the one to infer"),
        ("stats = vector_stats(frames.reshape(- 2, 3), len(frames))", "numpy (2.4) takes any negative size as the one to infer"),
        ('return stats if values.ndim > 0 else {k: v.reshape(1) if k != "count" else v for k, v in stats.items()}',
         "a 1-D feature's rows are (n, 1), so its statistics are already of shape (1,): the reshape changes nothing"),
        ('return stats if values.ndim > 1 else {k: v.reshape(1) if not k != "count" else v for k, v in stats.items()}',
         "a 1-D feature's statistics, count included, are already of shape (1,): which of them is reshaped changes nothing"),
        ('return stats if values.ndim > 1 else {k: v.reshape(1) if k == "count" else v for k, v in stats.items()}',
         "a 1-D feature's statistics, count included, are already of shape (1,): which of them is reshaped changes nothing"),
        ("counts = np.expand_dims(counts, axis=- 2)", "counts (episodes, 1) is widened only by axes of size 1: the same "
                                                      "shape wherever they go"),
        ('return stats if values.ndim >= 1 else {k: v.reshape(1) if k != "count" else v for k, v in stats.items()}',
         "a 1-D feature's rows are (n, 1), so its statistics are already of shape (1,): the reshape changes nothing"),
        ("if max(width, height) >= 299:  # LeRobot's `auto_downsample_height_width`",
         "at 299 pixels the step is int(299 / 150) = 1: every pixel is kept either way"),
        ("step = int(width / 150) if width >= height else int(height / 150)",
         "for a square frame width and height give the same step"),
        ("counts = np.expand_dims(counts, axis=+1)", "counts is (episodes, 1) and is widened only where every added "
                                                    "axis has size 1 (video statistics (3, 1, 1)): the same shape either way"),
    )},
}
"""(module path, the mutant's changed line stripped) → why that mutant cannot change what the module does."""
