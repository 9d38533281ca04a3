import gymnasium as gym
import numpy as np
import pytest


def test_rgb_array_frames_have_the_declared_shape_and_follow_the_attitude():
    env = gym.make("attitude_envs/ReactionWheel-v0", render_mode="rgb_array")
    env.reset(seed=0, options={"attitude": [0, 0, 0, 1.0], "target_attitude": [0, 0, 0, 1.0]})
    first = env.render()
    assert first.shape == (320, 480, 3) and first.dtype == np.uint8
    assert first.std() > 10  # not a blank canvas
    again = env.render()
    assert np.array_equal(first, again)  # same state, same picture
    env.reset(seed=0, options={"attitude": [0, 0, np.sin(0.6), np.cos(0.6)], "target_attitude": [0, 0, 0, 1.0]})
    turned = env.render()
    assert np.mean(np.any(turned != first, axis=-1)) > 0.005
    env.close()


def test_record_video_wrapper_collects_frames():
    env = gym.make("attitude_envs/ReactionWheel-v0", render_mode="rgb_array", episode_duration_s=0.3)
    env = gym.wrappers.RenderCollection(env)
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    frames = env.render()
    assert len(frames) == 4 and frames[0].shape == (320, 480, 3)


def test_record_video_writes_an_episode_video(tmp_path):
    pytest.importorskip("moviepy", reason="the 'video' extra (moviepy) is optional")
    env = gym.make("attitude_envs/ReactionWheel-v0", render_mode="rgb_array", episode_duration_s=1.0)
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = list(tmp_path.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
