"""Small writers of the inputs monovo reads besides PNG directories, for the tests: PDS3
products (attached or detached label), PDS4 products, videos (imageio-ffmpeg) and ROS 1/ROS 2
bags (rosbags). Each writes exactly what it is given; no downloads."""

from __future__ import annotations

from pathlib import Path

import numpy as np

MASK_12 = "2#0000111111111111#"


def _pds3_camera_group(camera: dict) -> list[str]:
    kind = camera["model"].upper()
    lines = ["GROUP = GEOMETRIC_CAMERA_MODEL", f"  MODEL_TYPE = {kind}",
             "  MODEL_COMPONENT_ID = (" + ", ".join(f'"{c}"' for c in kind) + ")"]
    for i, name in enumerate(kind, start=1):
        lines.append(f"  MODEL_COMPONENT_{i} = (" + ", ".join(repr(float(v)) for v in camera[name]) + ")")
    if kind == "CAHVORE":
        lines += [f"  MODEL_COMPONENT_8 = {camera.get('type', 3)}",
                  f"  MODEL_COMPONENT_9 = {camera.get('linearity', 1.0)!r}"]
    lines += ["  REFERENCE_COORD_SYSTEM_NAME = ROVER_NAV_FRAME", "END_GROUP = GEOMETRIC_CAMERA_MODEL"]
    return lines


def write_pds3(path: Path, image: np.ndarray, *, start_time: str | None = None,
               bit_mask: str | None = None, detached: bool = False,
               camera: dict | None = None) -> Path:
    """A PDS3 image product ``path`` (.IMG) of a (H, W) uint8 or uint16 image (MSB); with
    ``detached`` its label goes to ``path.with_suffix('.LBL')``. Returns the label's file."""
    path = Path(path)
    image = np.asarray(image)
    h, w = image.shape
    nbytes = image.dtype.itemsize
    data = image.astype(">u2").tobytes() if nbytes == 2 else image.astype(np.uint8).tobytes()
    stype = "MSB_UNSIGNED_INTEGER" if nbytes == 2 else "UNSIGNED_INTEGER"
    record = w * nbytes

    def label(label_records: int) -> str:
        pointer = f'("{path.name}", 1)' if detached else str(label_records + 1)
        lines = ["PDS_VERSION_ID = PDS3", "RECORD_TYPE = FIXED_LENGTH", f"RECORD_BYTES = {record}",
                 f"FILE_RECORDS = {h + (0 if detached else label_records)}"]
        if not detached:
            lines.append(f"LABEL_RECORDS = {label_records}")
        lines.append(f"^IMAGE = {pointer}")
        lines.append('INSTRUMENT_ID = "NAVCAM_LEFT"')
        if start_time is not None:
            lines.append(f"START_TIME = {start_time}")
        if camera is not None:
            lines += _pds3_camera_group(camera)
        lines += ["OBJECT = IMAGE", f"  LINES = {h}", f"  LINE_SAMPLES = {w}",
                  f"  SAMPLE_TYPE = {stype}", f"  SAMPLE_BITS = {8 * nbytes}", "  BANDS = 1"]
        if bit_mask is not None:
            lines.append(f"  SAMPLE_BIT_MASK = {bit_mask}")
        lines += ["END_OBJECT = IMAGE", "END"]
        return "\r\n".join(lines) + "\r\n"

    if detached:
        lbl = path.with_suffix(".LBL")
        lbl.write_text(label(0))
        path.write_bytes(data)
        return lbl
    n = 1
    while len(label(n).encode()) > n * record:
        n += 1
    path.write_bytes(label(n).encode().ljust(n * record, b" ") + data)
    return path


def _pds4_camera_xml(camera: dict) -> str:
    kind = camera["model"].upper()
    parts = {"C": ("Vector_Center", ("x_position", "y_position", "z_position")),
             "A": ("Vector_Axis", ("x_unit", "y_unit", "z_unit")),
             "H": ("Vector_Horizontal", ("x_pixel", "y_pixel", "z_pixel")),
             "V": ("Vector_Vertical", ("x_pixel", "y_pixel", "z_pixel")),
             "O": ("Vector_Optical", ("x_unit", "y_unit", "z_unit")),
             "R": ("Radial_Terms", ("c0", "c1", "c2")),
             "E": ("Entrance_Terms", ("c0", "c1", "c2"))}
    out = [f"<geom:Camera_Model_Parameters><geom:model_type>{kind}</geom:model_type>",
           f"<geom:{kind}_Model>"]
    for name in kind:
        block, keys = parts[name]
        out.append(f"<geom:{block}>" + "".join(f"<geom:{k}>{float(v)!r}</geom:{k}>"
                                                for k, v in zip(keys, camera[name]))
                   + f"</geom:{block}>")
    if kind == "CAHVORE":
        out.append(f"<geom:cahvore_model_type>{camera.get('type', 3)}</geom:cahvore_model_type>"
                   f"<geom:cahvore_model_parameter>{camera.get('linearity', 1.0)!r}"
                   "</geom:cahvore_model_parameter>")
    out.append(f"</geom:{kind}_Model>")
    out.append("<geom:Coordinate_Space_Reference><geom:Coordinate_Space_Indexed>"
               "<geom:coordinate_space_frame_type>ROVER_NAV_FRAME</geom:coordinate_space_frame_type>"
               "</geom:Coordinate_Space_Indexed></geom:Coordinate_Space_Reference>")
    out.append("</geom:Camera_Model_Parameters>")
    return "\n".join(out)


def write_pds4(label_path: Path, image: np.ndarray, *, start_time: str | None = None,
               bits: int | None = None, camera: dict | None = None,
               data_name: str | None = None) -> Path:
    """A PDS4 product: the label ``label_path`` (.xml) and its raw data file (``data_name``,
    default the label's name with ``.img``) of a (H, W) uint8 or uint16 (MSB) image."""
    label_path = Path(label_path)
    image = np.asarray(image)
    h, w = image.shape
    data_name = data_name or label_path.with_suffix(".img").name
    if image.dtype.itemsize == 2:
        dtype, raw = "UnsignedMSB2", image.astype(">u2").tobytes()
    else:
        dtype, raw = "UnsignedByte", image.astype(np.uint8).tobytes()
    (label_path.parent / data_name).write_bytes(raw)
    time = (f"<Time_Coordinates><start_date_time>{start_time}</start_date_time>"
            f"<stop_date_time>{start_time}</stop_date_time></Time_Coordinates>"
            if start_time else "")
    sampling = ""
    if bits is not None:
        mask = "2#" + "0" * (8 * image.dtype.itemsize - bits) + "1" * bits
        sampling = (f"<img:Imaging><img:Commanded_Parameters><img:Sampling><img:sample_bits>16"
                    "</img:sample_bits></img:Sampling></img:Commanded_Parameters>"
                    f"<img:Sampling><img:sample_bits>{bits}</img:sample_bits>"
                    f"<img:sample_bit_mask>{mask}</img:sample_bit_mask></img:Sampling></img:Imaging>")
    geometry = f"<geom:Geometry>{_pds4_camera_xml(camera)}</geom:Geometry>" if camera else ""
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<Product_Observational xmlns="http://pds.nasa.gov/pds4/pds/v1"
    xmlns:geom="http://pds.nasa.gov/pds4/geom/v1" xmlns:img="http://pds.nasa.gov/pds4/img/v1">
  <Identification_Area>
    <logical_identifier>urn:nasa:pds:monovo_test:data:{label_path.stem.lower()}</logical_identifier>
    <version_id>1.0</version_id>
    <title>monovo test frame</title>
    <information_model_version>1.20.0.0</information_model_version>
    <product_class>Product_Observational</product_class>
  </Identification_Area>
  <Observation_Area>
    {time}
    <Discipline_Area>{sampling}{geometry}</Discipline_Area>
  </Observation_Area>
  <File_Area_Observational>
    <File><file_name>{data_name}</file_name></File>
    <Array_2D_Image>
      <local_identifier>image</local_identifier>
      <offset unit="byte">0</offset>
      <axes>2</axes>
      <axis_index_order>Last Index Fastest</axis_index_order>
      <Element_Array><data_type>{dtype}</data_type></Element_Array>
      <Axis_Array><axis_name>Line</axis_name><elements>{h}</elements><sequence_number>1</sequence_number></Axis_Array>
      <Axis_Array><axis_name>Sample</axis_name><elements>{w}</elements><sequence_number>2</sequence_number></Axis_Array>
    </Array_2D_Image>
  </File_Area_Observational>
</Product_Observational>
"""
    label_path.write_text(xml)
    return label_path


def utc(seconds: float) -> str:
    """A PDS time string (``YYYY-MM-DDTHH:MM:SS.ffffff``) of Unix-epoch ``seconds``."""
    import datetime

    t = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=seconds)
    return t.strftime("%Y-%m-%dT%H:%M:%S.%f")


def write_video(path: Path, frames: list[np.ndarray], *, fps: float = 10.0,
                codec: str = "ffv1", quality: float | None = None) -> Path:
    """Grey uint8 frames into a video: ``ffv1`` (lossless, grey) or ``libx264`` (yuv420p)."""
    import imageio_ffmpeg

    h, w = frames[0].shape
    if codec == "ffv1":
        writer = imageio_ffmpeg.write_frames(str(path), (w, h), pix_fmt_in="gray", pix_fmt_out="gray",
                                             codec="ffv1", fps=fps, macro_block_size=1,
                                             output_params=["-level", "3"])
    else:
        writer = imageio_ffmpeg.write_frames(str(path), (w, h), pix_fmt_in="gray",
                                             pix_fmt_out="yuv420p", codec=codec, fps=fps,
                                             quality=quality, macro_block_size=16)
    writer.send(None)
    for f in frames:
        writer.send(np.ascontiguousarray(f, dtype=np.uint8))
    writer.close()
    return Path(path)


def _header(Header, Time, stamp_ns: int):
    stamp = Time(sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9))
    if "seq" in Header.__dataclass_fields__:  # ROS 1
        return Header(seq=0, stamp=stamp, frame_id="navcam")
    return Header(stamp=stamp, frame_id="navcam")


def _image_message(typestore, image: np.ndarray, stamp_ns: int, encoding: str,
                   bigendian: bool = False):
    Image = typestore.types["sensor_msgs/msg/Image"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    image = np.ascontiguousarray(image)
    h, w = image.shape[:2]
    ch = 1 if image.ndim == 2 else image.shape[2]
    big = bool(bigendian and image.dtype.itemsize > 1)
    data = image.astype(image.dtype.newbyteorder(">" if big else "<")).tobytes()
    return Image(header=_header(Header, Time, stamp_ns), height=h, width=w, encoding=encoding,
                 is_bigendian=int(big), step=w * ch * image.dtype.itemsize,
                 data=np.frombuffer(data, dtype=np.uint8))


def _compressed_message(typestore, png: bytes, stamp_ns: int):
    Msg = typestore.types["sensor_msgs/msg/CompressedImage"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    return Msg(header=_header(Header, Time, stamp_ns), format="png", data=np.frombuffer(png, dtype=np.uint8))


def write_bag(path: Path, frames: list[np.ndarray], stamps_ns: list[int], *, ros: int = 2,
              topic: str = "/navcam/image_raw", encoding: str = "mono8",
              compressed: bool = False, extra_topics: dict[str, list[np.ndarray]] | None = None,
              bag_ns: list[int] | None = None, bigendian: bool = False) -> Path:
    """A ROS 2 bag directory (``ros=2``, sqlite3) or a ROS 1 ``.bag`` file of ``frames`` on
    ``topic`` (sensor_msgs/Image, or CompressedImage PNGs), stamped ``stamps_ns`` (header) and
    recorded at ``bag_ns`` (default: the stamps + 1 ms)."""
    import cv2
    from rosbags.typesys import Stores, get_typestore

    if ros == 2:
        from rosbags.rosbag2 import Writer

        typestore = get_typestore(Stores.ROS2_HUMBLE)
        writer = Writer(Path(path), version=8)
    else:
        from rosbags.rosbag1 import Writer

        typestore = get_typestore(Stores.ROS1_NOETIC)
        writer = Writer(Path(path))
    bag_ns = bag_ns or [int(t) + 1_000_000 for t in stamps_ns]
    msgtype = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    serialize = typestore.serialize_cdr if ros == 2 else typestore.serialize_ros1
    with writer:
        conn = writer.add_connection(topic, msgtype, typestore=typestore)
        extra = {t: writer.add_connection(t, "sensor_msgs/msg/Image", typestore=typestore)
                 for t in (extra_topics or {})}
        for k, (img, t, b) in enumerate(zip(frames, stamps_ns, bag_ns)):
            if compressed:
                msg = _compressed_message(typestore, cv2.imencode(".png", img)[1].tobytes(), t)
            else:
                msg = _image_message(typestore, img, t, encoding, bigendian)
            writer.write(conn, int(b), serialize(msg, msgtype))
            for name, c in extra.items():
                other = _image_message(typestore, extra_topics[name][k], t, "mono8")
                writer.write(c, int(b) + 1, serialize(other, "sensor_msgs/msg/Image"))
    return Path(path)


def twelve_bit(frame: np.ndarray) -> np.ndarray:
    """An 8-bit frame as the 12-bit samples whose top 8 bits it is (value * 16)."""
    return frame.astype(np.uint16) * 16
