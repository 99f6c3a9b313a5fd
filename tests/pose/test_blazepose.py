"""BlazePose with MediaPipe's region of interest, and feet hung from another model's body."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from pipeline.pose.models.pose import BlazePose, BodyAndFeet, TinyPose, roi_transform
from pipeline.pose.models.session import create_session


@pytest.fixture(scope="module")
def blazepose(models_dir: Path) -> BlazePose:
    return BlazePose(create_session(models_dir / "blazepose_full.onnx"))


@pytest.fixture(scope="module")
def dancer(media_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    image = cv2.imread(str(media_dir / "images/dance_frame100.jpg"))
    h, w = image.shape[:2]
    return image, np.array([[0.15 * w, 0.05 * h, 0.85 * w, 0.98 * h]], np.float32)


def test_the_roi_puts_the_hips_at_the_centre_and_the_head_straight_up() -> None:
    hips, above_head = np.array([300.0, 200.0]), np.array([400.0, 200.0])  # a body lying to the right
    m = roi_transform(hips, above_head, 256, scale=1.25)
    crop = lambda p: m[:, :2] @ p + m[:, 2]  # noqa: E731
    assert np.allclose(crop(hips), [128, 128])
    assert np.allclose(crop(above_head), [128, 128 - 256 / 2.5])  # side = 2 x 100 x 1.25 = 250 px


def test_an_upside_down_dancer_gets_the_same_skeleton(blazepose: BlazePose, dancer) -> None:
    image, box = dancer
    h, w = image.shape[:2]
    upright = blazepose.estimate(image, box)
    flipped = blazepose.estimate(cv2.rotate(image, cv2.ROTATE_180), np.array([[w - box[0, 2], h - box[0, 3],
                                                                                w - box[0, 0], h - box[0, 1]]]))
    back = np.column_stack([w - flipped.keypoints[0, :, 0], h - flipped.keypoints[0, :, 1]])
    height = box[0, 3] - box[0, 1]
    assert np.median(np.linalg.norm(back - upright.keypoints[0, :, :2], axis=1)) <= 0.03 * height
    # Left stays left: after turning back, the left shoulder is where it was upright.
    left, right = upright.keypoints[0, 5, :2], upright.keypoints[0, 6, :2]
    assert np.linalg.norm(back[5] - left) < np.linalg.norm(back[5] - right)
    # Without the orientation check (upright first crop only), the inverted dancer comes out wrong.
    unchecked = BlazePose(blazepose.session, orientation_check=-np.inf)
    one_pass = unchecked.estimate(cv2.rotate(image, cv2.ROTATE_180), np.array(
        [[w - box[0, 2], h - box[0, 3], w - box[0, 0], h - box[0, 1]]]))
    back1 = np.column_stack([w - one_pass.keypoints[0, :, 0], h - one_pass.keypoints[0, :, 1]])
    assert np.median(np.linalg.norm(back1 - upright.keypoints[0, :, :2], axis=1)) > 2 * np.median(
        np.linalg.norm(back - upright.keypoints[0, :, :2], axis=1))


def test_world_landmarks_are_metric_and_turn_with_the_image(blazepose: BlazePose, dancer) -> None:
    image, box = dancer
    up = blazepose.estimate(image, box).world[0]
    h, w = image.shape[:2]
    down = blazepose.estimate(cv2.rotate(image, cv2.ROTATE_180), np.array(
        [[w - box[0, 2], h - box[0, 3], w - box[0, 0], h - box[0, 1]]])).world[0]
    shin = np.linalg.norm(up[25] - up[27])  # left knee to left ankle
    assert 0.25 < shin < 0.6  # metres
    assert up[0, 1] < up[27, 1]  # upright: the nose is above (smaller y than) the ankle
    assert down[0, 1] > down[27, 1]  # the image turned: so do the world landmarks' x, y


def test_feet_hang_from_the_body_models_ankles(models_dir: Path, blazepose: BlazePose, dancer) -> None:
    image, box = dancer
    body = TinyPose(create_session(models_dir / "tinypose_256x192.onnx"))
    both = BodyAndFeet(body, blazepose).estimate(image, box)
    assert np.array_equal(both.keypoints, body.estimate(image, box).keypoints)
    height = box[0, 3] - box[0, 1]
    for foot, ankle in ((0, 15), (1, 16), (2, 15), (3, 16)):  # heels, then toes
        assert both.feet[0, foot, 2] > 0.5
        assert np.linalg.norm(both.feet[0, foot, :2] - both.keypoints[0, ankle, :2]) < 0.12 * height
    assert both.world is not None and both.world.shape == (1, 33, 3)


def test_a_frames_crops_go_in_one_call_and_give_what_the_published_batch_of_one_gives(models_dir: Path,
                                                                                        media_dir: Path) -> None:
    from pipeline.pose.models.pose import crop_transform

    image = cv2.imread(str(media_dir / "images/human-pose.jpg"))
    h, w = image.shape[:2]
    # Five boxes: the whole picture, its halves and a corner (people or not, the crops differ).
    boxes = np.array([[0, 0, w, h], [0, 0, w / 2, h], [w / 2, 0, w, h], [0, 0, w / 3, h / 3],
                      [w / 4, h / 4, 3 * w / 4, h]], np.float32)
    for path, wrapper in ((models_dir / "tinypose_256x192.onnx", TinyPose),
                          (models_dir / "blazepose_full.onnx", BlazePose)):
        published = create_session(path)
        edited = create_session(path, any_batch=True)
        assert published.get_inputs()[0].shape[0] == 1 and edited.get_inputs()[0].shape[0] == "batch"
        calls = []
        run = edited.run
        edited.run = lambda names, feed, *a: calls.append(len(next(iter(feed.values())))) or run(names, feed, *a)
        one_by_one, batched = wrapper(published).estimate(image, boxes), wrapper(edited).estimate(image, boxes)
        np.testing.assert_allclose(batched.keypoints, one_by_one.keypoints, atol=1e-4)
        np.testing.assert_allclose(batched.feet, one_by_one.feet, atol=1e-4)
        assert calls[0] == 5  # every person's first pass at once
        # A ROI per person (the feet model after the body model): one call for the frame.
        if wrapper is BlazePose:
            rois = [crop_transform(b, 256, 256) for b in boxes]
            calls.clear()
            np.testing.assert_allclose(BlazePose(edited).estimate_in_rois(image, rois, boxes).feet,
                                       BlazePose(published).estimate_in_rois(image, rois, boxes).feet, atol=1e-4)
            assert calls == [5]



def _has_a_mask(session) -> bool:
    return any(len(o.shape) == 4 and o.shape[-1] == 1 for o in session.get_outputs())


def test_blazepose_runs_without_its_unused_segmentation_mask_and_gives_the_same_poses_bit_for_bit(
        models_dir: Path, default_models, dancer) -> None:
    # The mask's decoder is half of the model's cost, and nothing here reads the mask.
    image, box = dancer
    path = models_dir / "blazepose_full.onnx"
    published = create_session(path)
    pruned = create_session(path, unused_outputs=BlazePose.unused_output)
    assert _has_a_mask(published) and not _has_a_mask(pruned)
    assert len(pruned.get_outputs()) == len(published.get_outputs()) - 1
    roi = [BlazePose(published)._first_crop(box[0])[0]]
    for a, b in ((BlazePose(published).estimate(image, box), BlazePose(pruned).estimate(image, box)),  # alone
                 (BlazePose(published).estimate_in_rois(image, roi, box),  # as the feet model
                  BlazePose(pruned).estimate_in_rois(image, roi, box))):
        for field in ("keypoints", "feet", "world"):
            assert np.array_equal(getattr(a, field), getattr(b, field))
    assert not _has_a_mask(default_models[0].pose.feet.session)  # the stage's loader drops it too
    # On a GPU both edits apply: a free batch, and no mask.
    both = create_session(path, any_batch=True, unused_outputs=BlazePose.unused_output)
    assert both.get_inputs()[0].shape[0] == "batch" and not _has_a_mask(both)
    two = np.concatenate([box, box * np.float32(0.9)])
    np.testing.assert_allclose(BlazePose(both).estimate(image, two).feet,
                               BlazePose(published).estimate(image, two).feet, atol=1e-4)


def test_on_the_cpu_crops_go_one_per_call_and_on_a_gpu_a_frames_crops_at_once(default_models,
                                                                               monkeypatch) -> None:
    # Measured on 2 cores: one call on five TinyPose crops costs 25 % more than five calls (its
    # activations overflow the core's cache), on five BlazePose crops the same; a GPU wants the batch.
    import onnxruntime

    from pipeline.pose.models.loading import batch_crops
    from pipeline.pose.models.session import CPU, CUDA

    models = default_models[0]  # the stage's loader, with params.yaml's pose2d models
    assert models.pose.body.session.get_inputs()[0].shape[0] == 1
    assert models.pose.feet.session.get_inputs()[0].shape[0] == 1
    assert not batch_crops("cpu") and not batch_crops("auto")  # this onnxruntime has no CUDA
    monkeypatch.setattr(onnxruntime, "get_available_providers", lambda: [CUDA, CPU])
    assert batch_crops("auto") and batch_crops("cuda") and not batch_crops("cpu")
