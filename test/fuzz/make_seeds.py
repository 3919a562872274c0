#!/usr/bin/env python3
"""Writes the seed corpora of test/fuzz/corpus/<harness>/ (committed; rerun after a format change).

Seeds are well-formed examples of each format, taken from the repository's own files and from the
pty emulators' encoders (test/emulators/), plus a few near misses, so that the fuzzers start inside
the grammar. Usage: python3 test/fuzz/make_seeds.py (from the repository root)."""
import os
import struct
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "test", "emulators"))
from aurora_emulator import ascii_reply, crc16_arc, encode_bx, encode_tx  # noqa: E402

CORPUS = os.path.join(ROOT, "test", "fuzz", "corpus")


def write(harness, name, data):
    d = os.path.join(CORPUS, harness)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def from_file(harness, name, path):
    with open(os.path.join(ROOT, path), "rb") as f:
        write(harness, name, f.read())


def aurora():
    for i, text in enumerate(["OKAY", "ERROR0C", "WARNING01", "RESET", "020A0010B001", "01", "0A1F",
                              "030A0010B0010C001"]):
        write("fuzz_aurora_ascii", "reply%d" % i, ascii_reply(text)[:-1])
    write("fuzz_aurora_ascii", "bad_crc", b"OKAY0000")
    valid = dict(handle=0x0A, status=1, q=(1, 0, 0, 0), t_mm=(10.0, -20.0, -150.0), rms_mm=0.2, port=0x31,
                 frame=1234)
    base = dict(handle=0x0B, status=1, q=(0.7071, 0, 0.7071, 0), t_mm=(0, 0, -200.0), rms_mm=0.1, port=0x31,
                frame=1234)
    missing = dict(handle=0x0C, status=2, port=0x40, frame=1234)
    disabled = dict(handle=0x0D, status=4)
    two = encode_bx([valid, base])
    write("fuzz_aurora_bx", "two_valid", b"\x07" + two)
    write("fuzz_aurora_bx", "mixed", b"\x00" + encode_bx([valid, missing, disabled], system_status=0x0001))
    write("fuzz_aurora_bx", "stream", b"\x03" + two + b"garbage" + two[:9] + two)
    write("fuzz_aurora_bx", "error_reply", b"\x10" + ascii_reply("ERROR0C") + two)
    write("fuzz_aurora_tx", "two_valid", encode_tx([valid, base]))
    write("fuzz_aurora_tx", "mixed", encode_tx([valid, missing, disabled], system_status=0x0001))
    write("fuzz_aurora_tx", "none", encode_tx([]))


def lines():
    for i, line in enumerate(["FLOW=123.4\r\n", "17,250.5,OK\n", "t 0.02 88.125\n", "42.0\t1\n", "FLOW=-1\n",
                              "17,nan,OK\n", "FLOW=1e400\n"]):
        write("fuzz_flow_line", "line%d" % i, bytes([i % 4]) + line.encode())
    for i, payload in enumerate(["A,0.2500,0.5000,1.0000", "N,busy", "V,0.0000,0.0000,0.0000", "A,1.5,0,0"]):
        write("fuzz_valve_reply", "line%d" % i, "%s*%02X\n" % (payload, crc16_free_xor(payload)))


def crc16_free_xor(payload):
    x = 0
    for c in payload.encode():
        x ^= c
    return x


def configs():
    for f in os.listdir(os.path.join(ROOT, "config", "scenes")):
        from_file("fuzz_scene_yaml", f, os.path.join("config", "scenes", f))
    from_file("fuzz_plant_yaml", "plant.yaml", "config/plant.yaml")
    for f in os.listdir(os.path.join(ROOT, "config", "plants")):
        from_file("fuzz_plant_yaml", f, os.path.join("config", "plants", f))
    from_file("fuzz_controller_yaml", "controller.yaml", "config/controller.yaml")
    from_file("fuzz_controller_yaml", "teleop.yaml", "config/teleop.yaml")
    rig = open(os.path.join(ROOT, "config", "rig.yaml")).read()
    write("fuzz_rig_yaml", "rig.yaml", "scene: /tmp/s.yaml\n" + rig.replace('port: ""', 'port: /dev/null'))
    from_file("fuzz_rig_yaml", "rig_plain.yaml", "config/rig.yaml")
    # First byte: the robot ('2': three jets; 'M': six actuators, every second one reversible).
    write("fuzz_calibration_csv", "basic.csv",
          "2# HydroJet samples\nq1,q2,q3,qw,qx,qy,qz\n0.1,0,0,1,0,0,0\n0,0.05,0.02,0.9998,0.0141,-0.0141,0\n")
    write("fuzz_calibration_csv", "reordered.csv", "2t, qw,qx,qy,qz, q3,q2,q1\n1.5,1,0,0,0,0.1,0.2,0.05\n")
    write("fuzz_calibration_csv", "six.csv",
          "Mq1,q2,q3,q4,q5,q6,qw,qx,qy,qz\n0.1,-0.05,0,0.02,0.01,-0.1,1,0,0,0\n")
    write("fuzz_rod_fk_batch", "batch.txt", "# fx fy fz mx my mz\n0.1 0 0 0 0 0\n0,0.05,0,0,0,0.001\n\n-0.1\t0\t0\t0\t0\t0\r\n")


aurora()
lines()
configs()
