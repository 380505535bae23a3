"""Tactile layouts: the official mapping files and the project's default layout."""
from __future__ import annotations

import json

import numpy as np
import pytest

from touchanything.core.errors import DataError
from touchanything.core.tactile_layout import TactileLayout, read_mapping


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
