# BugBot tag camera: OpenMV (H7) MicroPython script.
#
# Finds AprilTags (family 36h11) in each 320 x 240 grayscale frame and sends
# one frame per image over the UART at 115200 baud, in the format defined by
# the Rust crate `wire::camera_link` (wire/src/camera_link, see its module doc):
#
#   COBS( version u8 = 1 | counter u16 | count u8 (<= 8)
#         | count x (tag id u16, cx u16, cy u16, distance u16)
#         | CRC-16/CCITT-FALSE u16 over everything before it ) 0x00
#
# All multi-byte fields little-endian. cx and cy are in centipixels
# (1/100 px) from the image's top-left corner: 0..32000 and 0..24000.
# The camera faces forward and the image is not mirrored, so small cx is the
# robot's left.

import image
import sensor
import struct
import time
from pyb import UART

# Edge of the tag's black square, millimetres. Print the tags at this size.
TAG_SIZE_MM = 80

# Focal length in pixels for a 320 px wide image over a 120 degree view:
# (320 / 2) / tan(120 deg / 2) = 160 / 1.732 = 92.4 px.
FOCAL_PX = 92.4

IMAGE_W = 320
IMAGE_H = 240
MAX_DETECTIONS = 8
VERSION = 1

# UART 3 is on P4 (TX) and P5 (RX) of the OpenMV Cam.
uart = UART(3, 115200, timeout_char=1000)

sensor.reset()
sensor.set_pixformat(sensor.GRAYSCALE)
sensor.set_framesize(sensor.QVGA)
sensor.skip_frames(time=2000)
# AprilTag detection needs stable exposure, not auto gain hunting.
sensor.set_auto_gain(False)
sensor.set_auto_whitebal(False)


def value(obj, name):
    """Tag fields are methods on older firmware, properties on newer."""
    v = getattr(obj, name)
    return v() if callable(v) else v


def crc16_ccitt_false(data):
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF; b"123456789" -> 0x29B1."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            if crc & 0x8000:
                crc = ((crc << 1) ^ 0x1021) & 0xFFFF
            else:
                crc = (crc << 1) & 0xFFFF
    return crc


def cobs_encode(data):
    """Consistent Overhead Byte Stuffing: the result contains no 0x00."""
    out = bytearray()
    block = bytearray()
    for byte in data:
        if byte == 0:
            out.append(len(block) + 1)
            out.extend(block)
            block = bytearray()
        else:
            block.append(byte)
            if len(block) == 254:
                out.append(255)
                out.extend(block)
                block = bytearray()
    out.append(len(block) + 1)
    out.extend(block)
    return bytes(out)


def clamp(v, lo, hi):
    return max(lo, min(hi, v))


def side_px(corners):
    """Mean edge length of the tag's quadrilateral, pixels."""
    total = 0.0
    for i in range(4):
        x0, y0 = corners[i]
        x1, y1 = corners[(i + 1) % 4]
        total += ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5
    return total / 4


def distance_mm(tag):
    """Pinhole distance from apparent size. The wide lens distorts at the
    image edges, so expect a few percent error there."""
    side = side_px(value(tag, "corners"))
    if side < 1:
        return 0
    return clamp(int(FOCAL_PX * TAG_SIZE_MM / side), 0, 65535)


def build_frame(counter, tags):
    body = bytearray(struct.pack("<BHB", VERSION, counter, len(tags)))
    for tag_id, cx, cy, dist in tags:
        body.extend(struct.pack("<HHHH", tag_id, cx, cy, dist))
    body.extend(struct.pack("<H", crc16_ccitt_false(body)))
    return cobs_encode(body) + b"\x00"


counter = 0
clock = time.clock()
while True:
    clock.tick()
    img = sensor.snapshot()
    found = []
    for tag in img.find_apriltags(families=image.TAG36H11):
        cx = clamp(int(value(tag, "cxf") * 100), 0, IMAGE_W * 100)
        cy = clamp(int(value(tag, "cyf") * 100), 0, IMAGE_H * 100)
        found.append((value(tag, "id") & 0xFFFF, cx, cy, distance_mm(tag)))
    # Nearest tags first: they give the best position fix.
    found.sort(key=lambda t: t[3])
    uart.write(build_frame(counter, found[:MAX_DETECTIONS]))
    counter = (counter + 1) & 0xFFFF
