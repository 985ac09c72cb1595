#!/usr/bin/env python3
"""Writes the protobuf and ROS 2 MCAP test logs of tests/mcap_encodings.rs with the official
MCAP libraries (not railgrip), so the Rust readers are checked against independent writers.

    pip install mcap==1.6.0 mcap-protobuf-support==0.6.0 mcap-ros2-support==0.6.0 protobuf
    python3 tests/data/mcap/make_encodings.py

Outputs (next to this script):
- soap_160kmh_0c.protobuf.mcap, soap_160kmh_0c.ros2.mcap: the bundled archive's JSON run
  fixtures/archive/soap_160kmh_0c.mcap re-encoded message for message (same log times, same
  values, the "run" metadata record). protobuf: the radar as a Twist inside a message with a
  google.protobuf.Timestamp, the four tachometers as one message with a packed repeated double,
  each pressure as a google.protobuf.DoubleValue wrapper. ROS 2: geometry_msgs/TwistStamped,
  sensor_msgs/JointState (velocity[0..3]) and std_msgs/Float64 per pressure. The pipelines
  protobuf.toml and ros2.toml map them.
- small.protobuf.mcap, small.ros2.mcap: a few messages that exercise the decoders' corners
  (nested messages, unpacked and packed repeated fields, wrappers, zigzag and fixed integers,
  enums, absent fields, header stamps; a big-endian CDR message, strings, sequences, bounded
  strings and bounded sequences before and after
  the wanted field) and small.expected.json: the values the official decoders read back from
  those files for each field path (the test compares railgrip's reading with these).
"""

import json
import os
import struct

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf import timestamp_pb2, wrappers_pb2
from mcap.reader import make_reader
from mcap.writer import Writer as RawWriter
from mcap_protobuf.decoder import DecoderFactory as PbDecoderFactory
from mcap_protobuf.writer import Writer as PbWriter
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
SOURCE = os.path.join(ROOT, "fixtures", "archive", "soap_160kmh_0c.mcap")

SEP = "=" * 80 + "\n"

# ---------------------------------------------------------------- protobuf message types

F = descriptor_pb2.FieldDescriptorProto


def field(name, number, ftype, type_name=None, repeated=False, packed=None):
    f = F(name=name, number=number, type=ftype)
    f.label = F.LABEL_REPEATED if repeated else F.LABEL_OPTIONAL
    if type_name:
        f.type_name = type_name
    if packed is not None:
        f.options.packed = packed
    return f


def build_pool():
    pool = descriptor_pool.DescriptorPool()
    for dep in (timestamp_pb2, wrappers_pb2):
        fdp = descriptor_pb2.FileDescriptorProto()
        dep.DESCRIPTOR.CopyToProto(fdp)
        pool.Add(fdp)
    fdp = descriptor_pb2.FileDescriptorProto(
        name="railgrip_test.proto", package="railgrip.test", syntax="proto3"
    )
    fdp.dependency.extend(["google/protobuf/timestamp.proto", "google/protobuf/wrappers.proto"])
    msgs = {
        "Vector3": [field("x", 1, F.TYPE_DOUBLE), field("y", 2, F.TYPE_DOUBLE), field("z", 3, F.TYPE_DOUBLE)],
        "Twist": [
            field("linear", 1, F.TYPE_MESSAGE, ".railgrip.test.Vector3"),
            field("angular", 2, F.TYPE_MESSAGE, ".railgrip.test.Vector3"),
        ],
        "RadarSpeed": [
            field("timestamp", 1, F.TYPE_MESSAGE, ".google.protobuf.Timestamp"),
            field("frame_id", 2, F.TYPE_STRING),
            field("twist", 3, F.TYPE_MESSAGE, ".railgrip.test.Twist"),
        ],
        "Tachometers": [
            field("timestamp", 1, F.TYPE_MESSAGE, ".google.protobuf.Timestamp"),
            field("name", 2, F.TYPE_STRING, repeated=True),
            field("omega", 3, F.TYPE_DOUBLE, repeated=True),
        ],
        "Pressure": [
            field("timestamp", 1, F.TYPE_MESSAGE, ".google.protobuf.Timestamp"),
            field("bar", 2, F.TYPE_MESSAGE, ".google.protobuf.DoubleValue"),
        ],
        # The corner cases of small.protobuf.mcap.
        "Header": [
            field("stamp", 1, F.TYPE_MESSAGE, ".google.protobuf.Timestamp"),
            field("frame_id", 2, F.TYPE_STRING),
        ],
        "Sample": [
            field("label", 1, F.TYPE_STRING),
            field("value", 2, F.TYPE_FLOAT),
        ],
        "Corner": [
            field("header", 1, F.TYPE_MESSAGE, ".railgrip.test.Header"),
            field("samples", 2, F.TYPE_MESSAGE, ".railgrip.test.Sample", repeated=True),
            field("unpacked", 3, F.TYPE_SINT32, repeated=True, packed=False),
            field("packed", 4, F.TYPE_FIXED64, repeated=True),
            field("wrapped", 5, F.TYPE_MESSAGE, ".google.protobuf.Int64Value"),
            field("zigzag", 6, F.TYPE_SINT64),
            field("negative", 7, F.TYPE_INT32),
            field("sfixed", 8, F.TYPE_SFIXED32),
            field("flag", 9, F.TYPE_BOOL),
            field("mode", 10, F.TYPE_ENUM, ".railgrip.test.Mode"),
            field("absent", 11, F.TYPE_DOUBLE),
            field("twist", 12, F.TYPE_MESSAGE, ".railgrip.test.Twist"),
        ],
    }
    for name, fields in msgs.items():
        m = fdp.message_type.add(name=name)
        m.field.extend(fields)
    e = fdp.enum_type.add(name="Mode")
    e.value.add(name="MODE_OFF", number=0)
    e.value.add(name="MODE_BRAKE", number=7)
    pool.Add(fdp)
    return {
        name: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"railgrip.test.{name}"))
        for name in msgs
    }


# ---------------------------------------------------------------- ROS 2 message definitions

TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
TWIST = "MSG: geometry_msgs/Twist\nVector3  linear\nVector3  angular\n"
TWIST_STAMPED = (
    "std_msgs/Header header\ngeometry_msgs/Twist twist\n"
    + SEP + HEADER + SEP + TIME + SEP + TWIST + SEP + VECTOR3
)
JOINT_STATE = (
    "std_msgs/Header header\n\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"
    + SEP + HEADER + SEP + TIME
)
FLOAT64 = "# a comment line\nfloat64 data\n"


def stamp(ns):
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def read_source():
    """The JSON run: [(log_time, {topic: value})] in time order, and the run metadata."""
    rows = {}
    with open(SOURCE, "rb") as f:
        r = make_reader(f)
        metadata = {m.name: dict(m.metadata) for m in r.iter_metadata()}
        for _, channel, message in r.iter_messages(log_time_order=True):
            value = next(iter(json.loads(message.data).values()))
            rows.setdefault(message.log_time, {})[channel.topic] = value
    return sorted(rows.items()), metadata["run"]


def write_protobuf(rows, metadata, types, path):
    with open(path, "wb") as f:
        w = PbWriter(f)
        w._writer.add_metadata("run", metadata)
        for seq, (t, v) in enumerate(rows):
            def ts(m):
                m.timestamp.seconds = t // 1_000_000_000
                m.timestamp.nanos = t % 1_000_000_000
                return m

            radar = ts(types["RadarSpeed"](frame_id="radar"))
            radar.twist.linear.x = v["/radar/speed"]
            w.write_message("/radar/speed", radar, log_time=t, publish_time=t, sequence=seq)
            tacho = ts(types["Tachometers"](name=["a1", "a2", "a3", "a4"]))
            tacho.omega.extend(v[f"/axle{a}/omega"] for a in range(1, 5))
            w.write_message("/tachometers", tacho, log_time=t, publish_time=t, sequence=seq)
            for a in range(1, 5):
                p = ts(types["Pressure"]())
                p.bar.value = v[f"/axle{a}/brake_pressure"]
                w.write_message(f"/axle{a}/pressure", p, log_time=t, publish_time=t, sequence=seq)
        w.finish()


def write_ros2(rows, metadata, path):
    with open(path, "wb") as f:
        w = Ros2Writer(f)
        w._writer.add_metadata("run", metadata)
        twist = w.register_msgdef("geometry_msgs/msg/TwistStamped", TWIST_STAMPED)
        joints = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE)
        f64 = w.register_msgdef("std_msgs/msg/Float64", FLOAT64)
        for seq, (t, v) in enumerate(rows):
            header = {"stamp": stamp(t), "frame_id": "radar"}
            w.write_message(
                "/radar/twist",
                twist,
                {"header": header, "twist": {"linear": {"x": v["/radar/speed"], "y": 0.0, "z": 0.0},
                                             "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}},
                log_time=t, publish_time=t, sequence=seq,
            )
            w.write_message(
                "/joint_states",
                joints,
                {"header": {"stamp": stamp(t), "frame_id": "bogie"},
                 "name": ["axle1", "axle2", "axle3", "axle4"], "position": [],
                 "velocity": [v[f"/axle{a}/omega"] for a in range(1, 5)], "effort": []},
                log_time=t, publish_time=t, sequence=seq,
            )
            for a in range(1, 5):
                w.write_message(f"/axle{a}/pressure", f64, {"data": v[f"/axle{a}/brake_pressure"]},
                                log_time=t, publish_time=t, sequence=seq)
        w.finish()


def write_small_protobuf(types, path):
    with open(path, "wb") as f:
        w = PbWriter(f)
        for k in range(3):
            m = types["Corner"]()
            m.header.stamp.seconds = 1_700_000_000 + k
            m.header.stamp.nanos = 250_000_000 * k
            m.header.frame_id = "x" * (k + 1)
            for j in range(k + 2):
                m.samples.add(label=f"s{j}", value=0.5 * j + k)
            m.unpacked.extend([-3 - k, 4, -5])
            m.packed.extend([2**40 + k, 7])
            m.wrapped.value = -(2**40) - k
            m.zigzag = -123456789012 + k
            m.negative = -42 - k
            m.sfixed = -7 + k
            m.flag = k % 2 == 1
            m.mode = 7 if k else 0
            m.twist.angular.z = -1.25 * k
            w.write_message("/corner", m, log_time=1000 + k, publish_time=1000 + k, sequence=k)
        w.finish()


CORNER_ROS2 = (
    "std_msgs/Header header\nstring note\nint16[3] small\nuint8[] blob\n"
    "geometry_msgs/Vector3[] points\nint64 big\nfloat32 gain\nbool on\nfloat64 value # the wanted one\n"
    "string<=8 short\nint32[<=3] bounded\nstring[<=2] names\n"
    "int32 CONSTANT=5\n"
    + SEP + HEADER + SEP + TIME + SEP + VECTOR3
)


def cdr_corner(k, little):
    """One CorneredMsg in CDR written by hand (so one can be big endian)."""
    e = "<" if little else ">"
    body = bytearray()

    def put(fmt, *vals):
        size = struct.calcsize(e + fmt[0]) if fmt[0] != "s" else 1
        while len(body) % size:
            body.append(0)
        body.extend(struct.pack(e + fmt, *vals))

    def string(s):
        b = s.encode() + b"\0"
        put("I", len(b))
        body.extend(b)

    put("i", 1_700_000_100 + k)
    put("I", 5 + k)
    string("frame")
    string("note " * (k + 1))
    for x in (1, -2, 3 + k):
        put("h", x)
    put("I", 3 + k)
    body.extend(bytes(range(3 + k)))
    put("I", 2)
    for j in range(2):
        for x in (j, j + 0.5, -j - k):
            put("d", float(x))
    put("q", -(2**50) + k)
    put("f", 0.25 * (k + 1))
    put("B", k % 2)
    put("d", 1e3 / (k + 3))
    string("ab"[: k % 3])
    put("I", 2)
    for x in (-9 - k, 11):
        put("i", x)
    put("I", 1)
    string("n")
    return bytes([0, 1 if little else 0, 0, 0]) + bytes(body)


def write_small_ros2(path):
    with open(path, "wb") as f:
        w = RawWriter(f)
        w.start(profile="ros2", library="make_encodings.py")
        sid = w.register_schema("railgrip_test/msg/Corner", "ros2msg", CORNER_ROS2.encode())
        cid = w.register_channel("/corner", "cdr", sid)
        for k in range(3):
            w.add_message(cid, log_time=2000 + k, data=cdr_corner(k, little=(k != 1)),
                          publish_time=2000 + k, sequence=k)
        w.finish()


def get(obj, path):
    for part in path.split("."):
        name, _, idx = part.partition("[")
        obj = obj[name] if isinstance(obj, dict) else getattr(obj, name)
        if idx:
            obj = obj[int(idx[:-1])]
    if hasattr(obj, "value") and not isinstance(obj, (int, float)):
        obj = obj.value
    return float(obj)


PB_PATHS = [
    "header.stamp.seconds", "header.stamp.nanos", "samples[1].value", "samples[0].value",
    "unpacked[0]", "unpacked[2]", "packed[0]", "packed[1]", "wrapped", "zigzag", "negative",
    "sfixed", "flag", "mode", "absent", "twist.angular.z", "twist.linear.x",
]
ROS2_PATHS = [
    "header.stamp.sec", "header.stamp.nanosec", "small[2]", "blob[1]", "points[1].x",
    "points[0].z", "big", "gain", "on", "value", "bounded[1]", "bounded[0]",
]


def expected(path, factory, paths):
    """What the official decoder reads from `path` for each field path, per message."""
    out = []
    with open(path, "rb") as f:
        r = make_reader(f, decoder_factories=[factory()])
        for _, _, _, msg in r.iter_decoded_messages():
            out.append({p: get(msg, p) for p in paths})
    return out


def main():
    types = build_pool()
    rows, metadata = read_source()
    write_protobuf(rows, metadata, types, os.path.join(HERE, "soap_160kmh_0c.protobuf.mcap"))
    write_ros2(rows, metadata, os.path.join(HERE, "soap_160kmh_0c.ros2.mcap"))
    small_pb = os.path.join(HERE, "small.protobuf.mcap")
    small_ros2 = os.path.join(HERE, "small.ros2.mcap")
    write_small_protobuf(types, small_pb)
    write_small_ros2(small_ros2)
    with open(os.path.join(HERE, "small.expected.json"), "w") as f:
        json.dump(
            {
                "protobuf": {"paths": PB_PATHS, "messages": expected(small_pb, PbDecoderFactory, PB_PATHS)},
                "ros2": {"paths": ROS2_PATHS, "messages": expected(small_ros2, Ros2DecoderFactory, ROS2_PATHS)},
            },
            f,
            indent=1,
        )
        f.write("\n")


if __name__ == "__main__":
    main()
