"""Capture of a Ladybug head's raw sensor images into the head dataset format, end to end on the simulated rig
(its VLP-16 over UDP on loopback, its head's six sensors rendered in a child process), and which head the live
SDK camera's frames go with: a head file, the rig file's own head, the factory head read at start, or the
nominal head only when accepted."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from capture_helpers import capture_following, read_meta

from drivers.ladybug5 import HeadCalibration, HeadPolicy, HeadSource, save_head
from drivers.ladybug5.rig import scaled_ladybug5_rig
from drivers.ladybug5.sim import pixel_rays_optical, sensor_displays
from drivers.sim.motion import MotionRigSpec
from rigd.capture import ConfigError
from rigd.capture import sources as capture_sources
from rigd.capture.config import RigSettings, SdkSettings, load_settings
from rigd.capture.sources import sdk_head
from rigd.dataset import open_dataset
from rigd.dataset.records import HeadConfig

SENSOR_WIDTH = 64  # the simulated head's sensors: 64 x 54 px


def test_capture_writes_the_sensor_images_with_their_head(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RIGD_CONFIG", raising=False)
    spec = MotionRigSpec(scene="indoor", seed=3, stops=6, still_s=1.5, move_s=0.5, width=128, height=64,
                         frame_period_s=0.2, sensor_width=SENSOR_WIDTH)
    code, emitter = capture_following(tmp_path, spec, 2, _rig_file(tmp_path))
    start, scene, trajectory = emitter.spec.start_host_s, emitter.scene, emitter.trajectory
    out = tmp_path / "dataset"
    assert code == 0
    head = scaled_ladybug5_rig(SENSOR_WIDTH)
    dataset = open_dataset(out)
    assert len(dataset) == 2 and isinstance(dataset.rig.camera, HeadConfig)
    assert dataset.views == tuple(c.name for c in head.cameras) == ("cam0", "cam1", "cam2", "cam3", "cam4", "cam5")
    for sensor, camera in zip(dataset.rig.camera.sensors, head.cameras, strict=True):
        assert (sensor.camera.width, sensor.camera.height) == (camera.width, camera.height)
        np.testing.assert_allclose(sensor.camera.K, camera.K, atol=1e-12)
        np.testing.assert_allclose(sensor.camera.D, camera.D, atol=1e-12)
        np.testing.assert_allclose(sensor.T_head_camera.rotation, camera.R_head_camera, atol=1e-9)
        np.testing.assert_allclose(sensor.T_head_camera.translation_m, camera.t_head_camera_m, atol=1e-12)
    np.testing.assert_allclose(dataset.ground_truth.matrix, spec.T_camera_lidar.matrix, atol=1e-9)
    rays = [pixel_rays_optical(c) for c in head.cameras]
    for i, pair_dir in enumerate(dataset.pair_dirs):
        pair, meta = dataset.load_pair(i), read_meta(pair_dir)
        assert meta["camera"]["head_source"] == "factory" and len(pair.cloud) > 1000
        assert [im.shape for im in pair.images] == [(c.height, c.width, 3) for c in head.cameras]
        # Each image is its sensor's view at the frame's instant: the noise-free render of that sensor there.
        pose = trajectory.pose_at(meta["camera"]["host_time_s"] - start)
        for image, truth in zip(pair.images, sensor_displays(scene, pose, head.cameras, rays), strict=True):
            assert np.abs(image[..., 0].astype(float) - 255.0 * truth).mean() < 3.0
        panorama = (pair_dir / "panorama.png").read_bytes()
        assert panorama[:8] == b"\x89PNG\r\n\x1a\n"
        models = dataset.rig.camera.models()  # the LiDAR's points fall into every side sensor with the truth
        points_head = dataset.ground_truth.apply(pair.cloud.points_lidar)
        assert all(m.project(points_head)[1].sum() > 100 for m in models[:5])


def _rig_file(tmp_path: Path) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump({"lidar": {"model": "VLP-16"}}))
    return path


def _settings(tmp_path: Path, rig_file: Path | None = None, head_rig: Path | None = None) -> RigSettings:
    layout = tmp_path / "layout.yaml"
    layout.write_text("a layout\n")
    return RigSettings(path=head_rig, head=head_rig is not None, camera_source="sdk",
                       sdk=SdkSettings(layout=layout, rig_file=rig_file))


def test_the_live_head_is_a_file_the_rig_files_own_or_the_factory_one_never_nominal_unasked(tmp_path: Path) -> None:
    assert sdk_head(_settings(tmp_path), nominal_head=False) is HeadPolicy.FACTORY
    assert sdk_head(_settings(tmp_path), nominal_head=True) is HeadPolicy.NOMINAL
    nominal = HeadCalibration.nominal((16, 12))
    factory = replace(nominal, source=HeadSource.FACTORY, serial=17092345, description="camera 17092345 (test)")
    save_head(factory, tmp_path / "factory.yaml")
    head = sdk_head(_settings(tmp_path, tmp_path / "factory.yaml"), nominal_head=False)
    assert isinstance(head, HeadCalibration) and head.source is HeadSource.FACTORY and head.serial == 17092345
    save_head(nominal, tmp_path / "nominal.yaml")
    with pytest.raises(ConfigError, match="nominal head .*rigd camera export-head --out .*--nominal-head"):
        sdk_head(_settings(tmp_path, tmp_path / "nominal.yaml"), nominal_head=False)
    accepted = sdk_head(_settings(tmp_path, tmp_path / "nominal.yaml"), nominal_head=True)
    assert isinstance(accepted, HeadCalibration) and accepted.source is HeadSource.NOMINAL
    # A rig file whose camera is the head (the export's camera section pasted in) is the head itself.
    rig = tmp_path / "rig.yaml"
    exported = yaml.safe_load((tmp_path / "factory.yaml").read_text())
    rig.write_text(yaml.safe_dump({**exported, "lidar": {"model": "VLP-16"}, "camera": {**exported["camera"],
                                                                                         "source": "sdk"}}))
    settings = load_settings(rig)
    assert settings.head and (settings.width, settings.height) == (2048, 1024)
    from_rig = sdk_head(replace(settings, sdk=_settings(tmp_path).sdk), nominal_head=False)
    assert isinstance(from_rig, HeadCalibration) and from_rig.serial == 17092345
    assert from_rig.sizes == factory.sizes


class _Recorded:
    """Stands in for SdkCamera / SdkFrameSource: records how the feed builds it."""

    made: list[tuple[tuple, dict]] = []

    def __init__(self, *args, **kwargs) -> None:
        _Recorded.made.append((args, kwargs))


def test_the_sdk_feed_opens_the_configured_camera_with_its_grab_timeout(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(capture_sources.SdkLayout, "load", staticmethod(lambda path: "layout"))
    monkeypatch.setattr(capture_sources, "LadybugLibrary", lambda layout, library: ("library", layout, library))
    monkeypatch.setattr(capture_sources, "SdkCamera", type("Camera", (_Recorded,), {}))
    monkeypatch.setattr(capture_sources, "SdkFrameSource", type("Source", (_Recorded,), {}))
    _Recorded.made = []
    settings = _settings(tmp_path)
    settings = replace(settings, sdk=replace(settings.sdk, serial=17092345, grab_timeout_ms=750, library="libx.so"))
    feed = capture_sources._sdk_feed(settings, nominal_head=False)
    (camera_args, camera_kwargs), (source_args, source_kwargs) = _Recorded.made
    assert camera_args == (("library", "layout", "libx.so"),)
    assert camera_kwargs == {"serial": 17092345, "grab_timeout_ms": 750}
    assert source_kwargs["head"] is HeadPolicy.FACTORY
    assert (source_args[1].width, source_args[1].height) == (settings.width, settings.height)
    assert "17092345" in feed.describe
