"""Tactile layouts: the official mapping files and the project's default layout; and the layout files at their
edges, by value: the last cell and slot that are allowed and the first that are not, slot 0 as a real sensor, the
bend-cell file's checks, the grid ↔ raw conversions with leading axes, the error messages, and that the layout
cannot be changed once loaded."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from touchanything.core.errors import DataError
from touchanything.core.tactile_layout import TactileLayout, read_bend_cells, read_mapping


def test_official_files_give_217_cells_and_the_documented_split(official_dir):
    layout = TactileLayout.from_dir(official_dir)
    for h in range(2):
        assert layout.valid[h].sum() == 217
        assert layout.bend[h].sum() == 66
        assert layout.tactile[h].sum() == 151
        assert (~layout.valid[h]).sum() == 224
    assert len(layout.used_sensors(0)) == 138 and len(layout.used_sensors(1)) == 147
    assert np.array_equal(layout.valid[1], np.fliplr(layout.valid[0]))
    assert np.array_equal(layout.bend[1], np.fliplr(layout.bend[0]))


def test_right_hand_is_mirrored_from_key_r_20_minus_c(official_dir):
    layout = TactileLayout.from_dir(official_dir)
    right = json.loads((official_dir / "pressure_position_mapping_right.json").read_text())
    left = json.loads((official_dir / "pressure_position_mapping_left.json").read_text())
    for r in range(21):
        for c in range(21):
            assert layout.sensor_index[1, r, c] == right.get(f"{r},{20 - c}", -1)
            assert layout.sensor_index[0, r, c] == left.get(f"{r},{c}", -1)


def test_default_layout_has_the_official_geometry(official_dir):
    official, default = TactileLayout.from_dir(official_dir), TactileLayout.default()
    assert np.array_equal(official.valid, default.valid)
    assert np.array_equal(official.bend, default.bend)
    for rows, cols in ((slice(0, 2), slice(None)), (slice(18, 21), slice(None)), (slice(None), 0), (slice(None), 20)):
        assert not default.valid[:, rows, cols].any()


def test_grid_from_raw_places_sensors_and_nans(official_dir):
    layout = TactileLayout.from_dir(official_dir)
    raw = np.zeros((2, 256), np.uint8)
    raw[0, 254] = 200  # left key "2,1"
    raw[1, 225] = 100  # right key "2,1" → display cell (2, 19)
    grid = layout.grid_from_raw(raw)
    assert grid[0, 2, 1] == 200 and grid[1, 2, 19] == 100
    assert np.isnan(grid[~layout.valid]).all() and not np.isnan(grid[layout.valid]).any()


def test_raw_from_grid_inverts_grid_from_raw_on_the_default_layout():
    layout = TactileLayout.default()
    rng = np.random.default_rng(1)
    raw = np.zeros((5, 2, 256), np.float32)
    for h in range(2):
        raw[:, h, layout.used_sensors(h)] = rng.uniform(0, 255, size=(5, len(layout.used_sensors(h))))
    back = layout.raw_from_grid(layout.grid_from_raw(raw))
    assert np.allclose(back, raw)


def test_shared_sensor_cells_average(official_dir):
    layout = TactileLayout.from_dir(official_dir)
    grid = layout.grid_from_raw(np.full((2, 256), 10, np.float32))
    grid[0, 7, 1] = 40  # a bend cell sharing sensor 222 with rows 8–11
    raw = layout.raw_from_grid(grid)
    assert raw[0, 222] == pytest.approx((40 + 4 * 10) / 5)


@pytest.mark.parametrize("content, field", [
    ('{"2,1": 300}', 'key "2,1"'),
    ('{"2;1": 3}', 'key "2;1"'),
    ('{"25,1": 3}', 'key "25,1"'),
    ('{"2,1": "a"}', 'key "2,1"'),
    ('[1, 2]', None),
    ('{"2,1": 3', None),
])
def test_bad_mapping_files_name_file_and_key(tmp_path, content, field):
    path = tmp_path / "map.json"
    path.write_text(content)
    with pytest.raises(DataError) as err:
        read_mapping(path)
    assert str(path) in str(err.value)
    if field:
        assert field in str(err.value)


def test_bend_cell_outside_layout_is_an_error(tmp_path, official_dir):
    for name in ("pressure_position_mapping_left.json", "pressure_position_mapping_right.json"):
        (tmp_path / name).write_text((official_dir / name).read_text())
    bend = json.loads((official_dir / "hand_joint_positions.json").read_text())
    bend["left"].append({"key": "0,0", "row": 0, "col": 0, "sensor": 1})
    (tmp_path / "hand_joint_positions.json").write_text(json.dumps(bend))
    with pytest.raises(DataError, match="bend cell 0,0 is outside the layout"):
        TactileLayout.from_dir(tmp_path)


def test_missing_layout_file(tmp_path):
    with pytest.raises(DataError, match="file not found"):
        TactileLayout.from_dir(tmp_path)


# --- the layout files at their edges, by value ---------------------------------------------------------------------------
LEFT = {"0,0": 0, "0,1": 1, "5,5": 255, "20,20": 7, "3,3": 7}
RIGHT = {"0,0": 2, "1,20": 0}
"""A small layout: slot 0 in use on both hands, slot 7 shared by two left cells, the grid's last cell mapped."""


def write_layout(folder, left=LEFT, right=RIGHT, bend=None):
    bend = bend if bend is not None else {"left": [{"row": 0, "col": 0}], "right": [{"row": 1, "col": 0}]}
    (folder / "pressure_position_mapping_left.json").write_text(json.dumps(left))
    (folder / "pressure_position_mapping_right.json").write_text(json.dumps(right))
    (folder / "hand_joint_positions.json").write_text(json.dumps(bend))
    return folder


def test_a_small_layout_by_value(tmp_path):
    layout = TactileLayout.from_dir(write_layout(tmp_path))
    assert layout.source == str(tmp_path)
    assert layout.sensor_index.dtype == np.int16 and layout.sensor_index.shape == (2, 21, 21)
    assert layout.sensor_index[0, 0, 0] == 0 and layout.sensor_index[0, 5, 5] == 255 and layout.sensor_index[0, 20, 20] == 7
    assert layout.sensor_index[1, 0, 20] == 2 and layout.sensor_index[1, 1, 0] == 0  # right: key r,c → cell r,20-c
    assert layout.valid.sum(axis=(1, 2)).tolist() == [5, 2]  # slot 0 is a sensor
    assert layout.valid[0, 0, 0] and layout.valid[1, 1, 0] and not layout.valid[0, 1, 1]
    assert layout.bend[0, 0, 0] and layout.bend[1, 1, 0] and layout.bend.sum() == 2
    assert layout.tactile.sum(axis=(1, 2)).tolist() == [4, 1]
    mask = layout.nan_mask()
    assert mask.dtype == np.float32 and mask[0, 0, 0] == 0.0 and np.isnan(mask[0, 1, 1]) and np.isnan(mask).sum() == 2 * 441 - 7
    assert layout.used_sensors(0).tolist() == [0, 1, 7, 255] and layout.used_sensors(1).tolist() == [0, 2]


def test_grid_and_raw_with_leading_axes(tmp_path):
    layout = TactileLayout.from_dir(write_layout(tmp_path))
    raw = np.arange(3 * 2 * 256, dtype=np.float64).reshape(3, 2, 256)
    grid = layout.grid_from_raw(raw)
    assert grid.shape == (3, 2, 21, 21) and grid.dtype == np.float32
    assert grid[2, 0, 0, 0] == raw[2, 0, 0] and grid[1, 0, 5, 5] == raw[1, 0, 255] and grid[0, 1, 1, 0] == raw[0, 1, 0]
    assert grid[0, 1, 0, 20] == raw[0, 1, 2] and np.isnan(grid[:, :, 10, 10]).all()
    back = layout.raw_from_grid(grid)
    assert back.shape == (3, 2, 256) and back.dtype == np.float32
    used = np.zeros((2, 256), bool)
    used[0, [0, 1, 7, 255]] = used[1, [0, 2]] = True
    assert np.array_equal(back[:, used], raw[:, used]) and (back[:, ~used] == 0).all()
    grid[1, 0, 3, 3] = 100.0  # slot 7 is shared by cells 3,3 and 20,20: it gets their mean
    assert layout.raw_from_grid(grid)[1, 0, 7] == pytest.approx((100.0 + raw[1, 0, 7]) / 2)
    one = layout.hand_grid(raw[0, 1], 1)
    assert one.shape == (21, 21) and one[1, 0] == raw[0, 1, 0] and np.isnan(one).sum() == 441 - 2


@pytest.mark.parametrize("key, value, ok", [
    ("20,20", 255, True), ("0,0", 0, True),
    ("21,0", 1, False), ("0,21", 1, False), ("-1,0", 1, False), ("0,-1", 1, False), ("1,2,3", 1, False), ("1", 1, False),
    ("1,1", 256, False), ("1,1", -1, False), ("1,1", True, False), ("1,1", 1.0, False),
])
def test_the_edges_of_a_mapping_file(tmp_path, key, value, ok):
    path = tmp_path / "map.json"
    path.write_text(json.dumps({key: value}))
    if ok:
        grid = read_mapping(path)
        row, col = map(int, key.split(","))
        assert grid[row, col] == value and (grid >= 0).sum() == 1 and grid.min() == -1
        return
    with pytest.raises(DataError) as err:
        read_mapping(path)
    assert err.value.field == f'key "{key}"'


def test_an_empty_mapping_and_an_unreadable_file(tmp_path):
    path = tmp_path / "map.json"
    path.write_text("{}")
    with pytest.raises(DataError, match="non-empty object"):
        read_mapping(path)
    path.write_bytes(b"\xff\xfe{")
    with pytest.raises(DataError, match="not a readable JSON file"):
        read_mapping(path)
    with pytest.raises(DataError, match="file not found") as err:
        read_mapping(tmp_path / "absent.json")
    assert err.value.field is None


def test_a_layout_file_nested_too_deeply_is_a_data_error_not_a_crash(tmp_path):
    """The layout files are read by the same reader as the episode files (`json_files.read_json_file`)."""
    path = tmp_path / "hand_joint_positions.json"
    path.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(DataError, match=r"not a readable JSON file \(nested too deeply\)") as err:
        read_bend_cells(path)
    assert err.value.path == path


@pytest.mark.parametrize("bend, field, problem", [
    ([], None, "expected an object"),
    ({"left": []}, "right", "missing or not a list"),
    ({"left": {}, "right": []}, "left", "missing or not a list"),
    ({"left": [{"row": "x", "col": 1}], "right": []}, "left[0]", "expected integer"),
    ({"left": [], "right": [{"row": 1, "col": 1}, {"col": 1}]}, "right[1]", "expected integer"),
    ({"left": [None], "right": []}, "left[0]", "expected integer"),
    ({"left": [{"row": 21, "col": 0}], "right": []}, "left[0]", "cell 21,0 outside the grid"),
    ({"left": [], "right": [{"row": 0, "col": 21}]}, "right[0]", "cell 0,21 outside the grid"),
    ({"left": [{"row": -1, "col": 0}], "right": []}, "left[0]", "outside the grid"),
    ({"left": [{"row": 0, "col": -1}], "right": []}, "left[0]", "outside the grid"),
])
def test_the_checks_of_the_bend_cell_file(tmp_path, bend, field, problem):
    path = tmp_path / "hand_joint_positions.json"
    path.write_text(json.dumps(bend))
    with pytest.raises(DataError) as err:
        read_bend_cells(path)
    assert err.value.field == field and problem in err.value.problem


def test_bend_cells_at_the_grid_edges_and_on_slot_0(tmp_path):
    path = tmp_path / "hand_joint_positions.json"
    path.write_text(json.dumps({"left": [{"row": 20, "col": 20}, {"row": "0", "col": 0}], "right": [{"row": 20, "col": 0}]}))
    bend = read_bend_cells(path)
    assert bend.dtype == bool and bend.shape == (2, 21, 21)
    assert np.argwhere(bend).tolist() == [[0, 0, 0], [0, 20, 20], [1, 20, 0]]
    # A bend cell on a cell that reads slot 0 is inside the layout; one on an unmapped cell is not.
    write_layout(tmp_path, bend={"left": [{"row": 0, "col": 0}], "right": [{"row": 1, "col": 0}]})
    assert TactileLayout.from_dir(tmp_path).bend.sum() == 2
    write_layout(tmp_path, bend={"left": [], "right": [{"row": 1, "col": 20}]})
    with pytest.raises(DataError, match="bend cell 1,20 is outside the layout") as err:
        TactileLayout.from_dir(tmp_path)
    assert err.value.field == "right"


def test_the_messages_name_the_allowed_range_and_the_first_bend_cell_outside(tmp_path):
    path = tmp_path / "map.json"
    path.write_text(json.dumps({"1,1": 256}))
    with pytest.raises(DataError) as err:
        read_mapping(path)
    assert err.value.problem == "sensor index must be an integer 0–255"
    write_layout(tmp_path, bend={"left": [{"row": 9, "col": 9}], "right": [{"row": 1, "col": 0}, {"row": 4, "col": 4}]})
    with pytest.raises(DataError) as err:
        TactileLayout.from_dir(tmp_path)
    assert (err.value.field, err.value.problem) == ("left", "bend cell 9,9 is outside the layout")


def test_the_layout_is_frozen(tmp_path):
    layout = TactileLayout.from_dir(write_layout(tmp_path))
    with pytest.raises(dataclasses.FrozenInstanceError):
        layout.bend = np.zeros((2, 21, 21), bool)
