"""RGB-D frames from MRPT rawlogs (``CObservation3DRangeScan``, e.g. a Kinect's) as :class:`RGBDFrame`.

MRPT stores a depth camera's frame as one ``CObservation3DRangeScan`` (``libs/obs``,
``CObservation3DRangeScan.cpp``, versions 1 to 10): optionally the 3-D points (in the sensor frame:
x forward, y left, z up) with their pixel indices; the range image (``uint16`` in ``rangeUnits``
metres, 0 = no reading; depth along the optical axis when ``range_is_depth``); the intensity
(colour) image as a ``CImage``; a confidence image; the depth and colour cameras' intrinsics
(``TCamera``) and the colour camera's pose relative to the depth camera.

:func:`read_rgbd_frames` reads every such observation of a rawlog (bare or inside a
``CSensoryFrame``) into an :class:`RgbdObservation`: the depth image in metres (NaN where the
Kinect saw nothing: glass, black surfaces, too near or too far), the colour image (RGB), both
cameras' intrinsics and the stamp. :meth:`RgbdObservation.to_frame` gives the project's
:class:`~missiontree.types.RGBDFrame` in the depth camera's geometry (the Kinect's colour camera
sits about 2.5 cm beside it; in MRPT's sample frame the two images line up to within about 15
pixels, as if the driver had registered depth to colour, while the file gives the depth camera's
own intrinsics: geometry here uses those, colour is only read by region).

It sits with the other MRPT readers in ``mapping`` because the package's layers put ``perception``
below ``mapping``, and the MRPT archive primitives it shares with the rawlog reader live here.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from missiontree.mapping.mrpt_archive import ArchiveReader, load_archive_bytes, mrpt_time_to_unix
from missiontree.types import CameraIntrinsics, Pose2D, RGBDFrame

#: Largest image side read (pixels).
MAX_SIDE = 8192


@dataclass(frozen=True)
class RgbdObservation:
    """One ``CObservation3DRangeScan`` read.

    Attributes:
        stamp: Time of the frame (seconds since 1970; NaN when the file has none).
        depth: HxW float32 depth in metres along the optical axis, NaN where there is no reading.
        color: HxWx3 uint8 RGB image, or None when the frame has none.
        depth_camera: The depth camera's intrinsics.
        color_camera: The colour camera's intrinsics.
        max_range: The sensor's maximum range (m).
        label: MRPT's sensor label.
    """

    stamp: float
    depth: np.ndarray
    color: np.ndarray | None
    depth_camera: CameraIntrinsics
    color_camera: CameraIntrinsics
    max_range: float
    label: str = ""

    def to_frame(self, camera_pose: Pose2D | None = None, camera_height: float = 0.0) -> RGBDFrame:
        """The frame as an :class:`RGBDFrame` in the depth camera's geometry (colour resized to it)."""
        h, w = self.depth.shape
        color = self.color if self.color is not None else np.zeros((h, w, 3), np.uint8)
        if color.shape[:2] != (h, w):
            import cv2

            color = cv2.resize(color, (w, h), interpolation=cv2.INTER_AREA)
        return RGBDFrame(self.stamp, color, self.depth, self.depth_camera,
                         camera_pose or Pose2D(0.0, 0.0, 0.0), camera_height)


def read_rgbd_frames(path: str | Path) -> list[RgbdObservation]:
    """Every ``CObservation3DRangeScan`` of a rawlog, in file order.

    Raises:
        ArchiveError: The file cannot be read or holds an object of another class.
    """
    return list(iter_rgbd_frames(path))


def iter_rgbd_frames(path: str | Path) -> Iterator[RgbdObservation]:
    """``CObservation3DRangeScan`` observations of a rawlog one by one (see :func:`read_rgbd_frames`)."""
    reader = ArchiveReader(load_archive_bytes(path), str(path))
    while not reader.at_end():
        name, version, old = reader.header()
        if name == "CSensoryFrame":
            if version < 2:
                reader.u32("the frame's id")
            if version == 0:
                reader.u64("the frame's stamp")
            for _ in range(reader.u32("the observation count")):
                inner, inner_version, inner_old = reader.expect_header("CObservation3DRangeScan")
                yield _range_scan_3d(reader, inner_version)
                reader.end(inner, inner_old)
            reader.end(name, old)
        elif name == "CObservation3DRangeScan":
            yield _range_scan_3d(reader, version)
            reader.end(name, old)
        else:
            raise reader.error(f"an object of class {name!r} is not read by the RGB-D reader "
                               "(known: CObservation3DRangeScan, CSensoryFrame)")


def _range_scan_3d(reader: ArchiveReader, version: int) -> RgbdObservation:
    """A ``CObservation3DRangeScan`` after its header (MRPT's serializeFrom, versions 1 to 10)."""
    if not 1 <= version <= 10:
        raise reader.unknown_version("CObservation3DRangeScan", version, "1 to 10")
    max_range = reader.f32("the maximum range")
    reader.pose3d()  # the sensor's pose on the robot
    if reader.boolean("the points flag"):
        n = reader.u32("the point count")
        if n > MAX_SIDE * MAX_SIDE:
            raise reader.error(f"expected at most {MAX_SIDE * MAX_SIDE:,} points, found {n:,}")
        reader.take(n * 12 + (n * 4 if version >= 8 else 0), "the 3-D points")
    depth = np.zeros((0, 0), np.float32)
    has_range = reader.boolean("the range image flag")
    units = reader.f32("the range units") if version >= 9 else 1e-3
    if has_range:
        if version < 9:
            depth = reader.matrix().astype(np.float32)
        else:
            rows, cols = reader.u32("the range image rows"), reader.u32("the range image columns")
            _check_side(reader, rows, cols)
            values = reader.array("u2", rows * cols, "the range image").reshape(rows, cols)
            depth = values.astype(np.float32) * units
    depth[depth <= 0] = np.nan
    color = _image(reader) if reader.boolean("the intensity image flag") else None
    if reader.boolean("the confidence image flag"):
        _image(reader)
    depth_camera = _camera(reader)
    color_camera = depth_camera
    if version >= 4:
        color_camera = _camera(reader)
        reader.pose3d()  # the colour camera relative to the depth camera
    reader.f32("the range noise")
    stamp = mrpt_time_to_unix(reader.u64("the stamp"))
    label = reader.string("the sensor label")
    if version >= 3:
        for what in ("points", "range image"):
            if reader.boolean(f"the external {what} flag"):
                reader.string(f"the external {what} file")
                raise reader.error(f"the {what} is stored in an external file, which is not read")
            reader.string(f"the external {what} file")
    if version >= 5 and not reader.boolean("the depth flag"):
        raise reader.error("the range image holds ranges along rays, not depth; only depth is read")
    if version >= 6:
        reader.u8("the intensity channel")
    if version >= 7 and reader.boolean("the pixel labels flag"):
        raise reader.error("pixel labels are not read")
    if version >= 10:
        for _ in range(reader.u8("the layer count")):
            reader.string("the layer name")
            rows, cols = reader.u32("the layer rows"), reader.u32("the layer columns")
            _check_side(reader, rows, cols)
            reader.take(rows * cols * 2, "the layer")
    return RgbdObservation(stamp, depth, color, depth_camera, color_camera, max_range, label)


def _check_side(reader: ArchiveReader, rows: int, cols: int) -> None:
    if rows > MAX_SIDE or cols > MAX_SIDE:
        raise reader.error(f"expected an image of at most {MAX_SIDE} pixels a side, found {cols} x {rows}")


def _camera(reader: ArchiveReader) -> CameraIntrinsics:
    """A ``TCamera`` object (versions 2 to 6): the pinhole intrinsics and image size."""
    name, version, old = reader.expect_header("TCamera")
    if not 2 <= version <= 6:
        raise reader.unknown_version(name, version, "2 to 6")
    reader.f64("the focal length")
    reader.take(8 * (8 if version >= 3 else 5), "the distortion")
    if version >= 4:
        fx, fy, cx, cy = (float(v) for v in reader.unpack("dddd", "the intrinsics"))
    else:
        k = reader.matrix()
        fx, fy, cx, cy = float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
    rows, cols = reader.u32("the image rows"), reader.u32("the image columns")
    if version >= 5:
        reader.string("the camera name")
    if version >= 6:
        reader.u8("the distortion model")
    reader.end(name, old)
    return CameraIntrinsics(int(cols), int(rows), fx, fy, cx, cy)


def _image(reader: ArchiveReader) -> np.ndarray:
    """A ``CImage`` object (versions 2 to 9, stored in the file) as RGB (grey images repeated to RGB)."""
    name, version, old = reader.expect_header("CImage")
    if not 2 <= version <= 9:
        raise reader.unknown_version(name, version, "2 to 9")
    if version >= 6 and reader.boolean("the external image flag"):
        raise reader.error("the image is stored in an external file, which is not read")
    if not reader.u8("the colour flag"):  # grey: width, height, origin, size, [depth], [zip flag]
        width, height, _origin, size = (int(v) for v in reader.unpack("iiii", "the grey image header"))
        if version >= 9:
            reader.i32("the pixel depth")
        _check_side(reader, height, width)
        if version >= 5 and reader.boolean("the zip flag"):
            raise reader.error("zip-compressed grey images are not read")
        grey = reader.array("u1", size, "the grey image")[: width * height].reshape(height, width)
        image = np.repeat(grey[:, :, None], 3, axis=2)
    else:
        width, height = reader.i32("the image width"), reader.i32("the image height")
        if version < 7 or width > 0:  # a JPEG
            import cv2

            data = reader.array("u1", reader.u32("the JPEG size"), "the JPEG")
            bgr = cv2.imdecode(data, cv2.IMREAD_COLOR)
            if bgr is None:
                raise reader.error("the colour image's JPEG does not decode")
            image = bgr[:, :, ::-1].copy()
        else:  # raw BGR rows, the size negated
            width, height = -width, -height
            _check_side(reader, height, width)
            bgr = reader.array("u1", width * height * 3, "the colour image").reshape(height, width, 3)
            image = bgr[:, :, ::-1]
    reader.end(name, old)
    return np.ascontiguousarray(image)

