import numpy as np
import pytest

from dualpixel.errors import ParameterError
from dualpixel.synthesis.scenes import SceneConfig, render_scene_sequence


def test_scenes_are_seeded_any_size_with_exact_positive_depth():
    config = SceneConfig(width=97, height=53, frames=3, leaves=10)
    frames = render_scene_sequence(11, config)
    again = render_scene_sequence(11, config)
    other = render_scene_sequence(12, config)
    assert len(frames) == 3
    for (rgb, depth), (rgb2, depth2) in zip(frames, again):
        assert rgb.shape == (53, 97, 3) and depth.shape == (53, 97)
        assert rgb.dtype == np.float32 and depth.dtype == np.float32
        assert np.array_equal(rgb, rgb2) and np.array_equal(depth, depth2)
        assert np.isfinite(depth).all() and depth.min() > 0
        assert rgb.min() >= 0 and rgb.max() <= 1
    assert not np.array_equal(frames[0][0], other[0][0])


def test_scenes_hold_leaves_in_front_of_and_behind_focus_and_move():
    config = SceneConfig(width=160, height=120, frames=4, leaves=30)
    frames = render_scene_sequence(3, config)
    depth0 = frames[0][1]
    # piecewise-constant leaves at many depths over a smooth plane
    assert len(np.unique(depth0)) > 20
    assert depth0.min() < 6.0 < depth0.max()  # both sides of the presets' focus distances
    # smooth motion: consecutive frames differ, but far less than an unrelated scene does
    step = np.mean(np.abs(frames[1][0] - frames[0][0]))
    unrelated = np.mean(np.abs(render_scene_sequence(4, config)[0][0] - frames[0][0]))
    assert 0 < step < 0.6 * unrelated
    assert not np.array_equal(frames[1][1], depth0)  # depth changes with the motion too


def test_bad_scene_parameters():
    with pytest.raises(ParameterError, match="width"):
        SceneConfig(width=4)
    with pytest.raises(ParameterError, match="near"):
        SceneConfig(near=-1.0)
