"""Watches a running `teleop foxglove` as Foxglove would and decodes what it serves with
Foxglove's own ROS 2 decoder (`mcap-ros2-support`), from the `ros2msg` schema each
channel advertises: a check by hand against a live system, beside the Rust protocol test
(deploy/teleop/tests/foxglove.rs), which decodes with the project's own decoder.

    teleop launch &                      # or any running system
    teleop foxglove --port 8765 &
    python check_foxglove.py 8765 10     # subscribe to every channel for 10 s

The WebSocket client is the standard library's sockets (RFC 6455 by hand, subprotocol
`foxglove.sdk.v1`), so nothing of the Foxglove SDK is involved on this side. Prints one
line per topic (messages decoded, errors, a glimpse of the last message); exits 1 if a
message did not decode or a channel sent nothing."""

import base64
import json
import os
import socket
import struct
import sys
import time

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory


class Connection:
    def __init__(self, port: int):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.buf = b""
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
            ).encode()
        )
        while b"\r\n\r\n" not in self.buf:
            self._fill()
        head, self.buf = self.buf.split(b"\r\n\r\n", 1)
        status = head.decode(errors="replace").splitlines()[0]
        if " 101 " not in status:
            raise SystemExit(f"handshake refused: {status}")

    def _fill(self):
        chunk = self.sock.recv(1 << 20)
        if not chunk:
            raise EOFError("the server closed the connection")
        self.buf += chunk

    def _take(self, n: int) -> bytes:
        while len(self.buf) < n:
            self._fill()
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def _frame(self):
        b0, b1 = self._take(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._take(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._take(8))[0]
        return b0 & 0x0F, bool(b0 & 0x80), self._take(n)

    def receive(self):
        """The next whole message: (opcode, bytes)."""
        op, fin, data = self._frame()
        while not fin:
            _, fin, more = self._frame()
            data += more
        return op, data

    def send_text(self, text: str):
        data, mask = text.encode(), os.urandom(4)
        n = len(data)
        head = bytes([0x81]) + (
            bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n)
        )
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))


def glimpse(m) -> str:
    if hasattr(m, "ff"):
        return f"ff={m.ff:.3f} mf={m.mf:.3f} rf={m.rf:.3f} lf={m.lf:.3f} th={m.th:.3f}"
    if hasattr(m, "position") and hasattr(m, "name"):
        return f"{len(m.name)} joints, {m.name[0]}={m.position[0]:.3f}"
    if hasattr(m, "node_name"):
        return f"node {m.node_name}"
    if hasattr(m, "format"):
        return f"{m.format}, {len(m.data)} bytes, starts {bytes(m.data[:2]).hex()}"
    if hasattr(m, "pose"):
        p = m.pose.position
        return f"position {p.x:.3f} {p.y:.3f} {p.z:.3f}"
    return ""


def main():
    port, seconds = int(sys.argv[1]), float(sys.argv[2])
    ws = Connection(port)
    channels = {}
    # The server advertises its channels right after its serverInfo.
    until = time.time() + 2.0
    ws.sock.settimeout(0.5)
    while time.time() < until:
        try:
            op, data = ws.receive()
        except socket.timeout:
            continue
        if op == 1:
            m = json.loads(data)
            if m.get("op") == "advertise":
                for c in m["channels"]:
                    channels[c["id"]] = c
    if not channels:
        raise SystemExit("no channel advertised")
    subs = list(enumerate(channels))
    ws.send_text(
        json.dumps(
            {"op": "subscribe", "subscriptions": [{"id": s, "channelId": c} for s, c in subs]}
        )
    )
    by_sub = {s: channels[c] for s, c in subs}
    factory = DecoderFactory()
    decoded, errors, last = {}, {}, {}
    until = time.time() + seconds
    while time.time() < until:
        try:
            op, data = ws.receive()
        except socket.timeout:
            continue
        if op != 2 or data[0] != 0x01:
            continue
        sub, _log_time = struct.unpack("<IQ", data[1:13])
        c = by_sub[sub]
        # The factory keeps one decoder per schema id: one per channel.
        schema = Schema(
            id=c["id"], name=c["schemaName"], encoding=c["schemaEncoding"], data=c["schema"].encode()
        )
        topic = c["topic"]
        try:
            last[topic] = factory.decoder_for(c["encoding"], schema)(data[13:])
            decoded[topic] = decoded.get(topic, 0) + 1
        except Exception as e:  # noqa: BLE001 (any failure to decode is the finding)
            errors[topic] = errors.get(topic, 0) + 1
            if errors[topic] == 1:
                print(f"{topic}: {e}", file=sys.stderr)
    failed = False
    for c in sorted(channels.values(), key=lambda c: c["topic"]):
        t = c["topic"]
        n, e = decoded.get(t, 0), errors.get(t, 0)
        failed |= e > 0 or n == 0
        print(f"{t:46s} {c['schemaName']:36s} decoded {n:6d}  errors {e}  {glimpse(last.get(t))}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
