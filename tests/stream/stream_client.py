#!/usr/bin/python3
"""An independent client of the frame stream (docs/stream.md), on python3-websockets.

Run by tests/test_stream.cpp: stream_client.py PORT SCENARIO OUT_DIR [TOKEN]. Each scenario checks
what the protocol promises and exits 0, or prints what was wrong and exits 1. Frame payloads it
receives are written to OUT_DIR (frame-<n>.<encoding>) for the C++ test to decode.
"""
import asyncio
import json
import os
import struct
import sys
import time

import websockets

VIEW = {"eye": "-6,-12,8", "target": "7.5,0,0", "up": "0,0,1", "fov": 50, "w": 320, "h": 180,
        "mode": "interactive", "quality": 60}


def fail(message):
    print("FAIL: " + message, flush=True)
    sys.exit(1)


def expect(condition, message):
    if not condition:
        fail(message)


def unpack(message):
    expect(isinstance(message, bytes), "expected a binary frame, got %r" % (message[:200],))
    expect(message[:4] == b"PVF1", "a frame starts with PVF1")
    (length,) = struct.unpack("<I", message[4:8])
    header = json.loads(message[8:8 + length])
    return header, message[8 + length:]


class Stream:
    def __init__(self, ws, out):
        self.ws, self.out, self.texts = ws, out, []

    async def next_frame(self, timeout=20):
        """The next binary frame (text messages before it are kept in self.texts)."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            expect(left > 0, "no frame within %s s" % timeout)
            message = await asyncio.wait_for(self.ws.recv(), left)
            if isinstance(message, str):
                self.texts.append(json.loads(message))
                continue
            header, payload = unpack(message)
            with open(os.path.join(self.out, "frame-%d.%s" % (header["frame"], header["encoding"])), "wb") as f:
                f.write(payload)
            return header, payload

    async def next_text(self, timeout=10):
        if self.texts:
            return self.texts.pop(0)
        message = await asyncio.wait_for(self.ws.recv(), timeout)
        expect(isinstance(message, str), "expected a text message")
        return json.loads(message)

    async def view(self, seq, **changes):
        params = dict(VIEW)
        params.update(changes)
        await self.ws.send(json.dumps({"type": "view", "seq": seq, "params": params}))

    async def ack(self, frame):
        await self.ws.send(json.dumps({"type": "ack", "frame": frame}))


def uri(port):
    return "ws://127.0.0.1:%d/api/stream" % port


async def jpeg(port, out, token):
    async with websockets.connect(uri(port), subprotocols=["plantview.v1"], max_size=None) as ws:
        expect(ws.subprotocol == "plantview.v1", "the server answers the subprotocol plantview.v1")
        s = Stream(ws, out)
        await ws.send(json.dumps({"type": "hello", "codec": "jpeg"}))
        ready = await s.next_text()
        expect(ready == {"type": "ready", "codec": "jpeg", "protocol": 1}, "ready: %r" % ready)
        await s.view(1)
        header, payload = await s.next_frame()
        expect(header["seq"] == 1 and header["frame"] == 1, "frame 1 answers view 1: %r" % header)
        expect(header["encoding"] == "jpeg" and payload[:2] == b"\xff\xd8", "a JPEG: %r" % header)
        expect(header["width"] == 320 and header["height"] == 180 and not header["still"], "%r" % header)
        expect("X-Triangles" in header["stats"] and header["key"], "stats: %r" % header)
        await s.ack(1)
        # At rest: the still of view 1, unasked, full quality (PNG).
        header, payload = await s.next_frame(timeout=10)
        expect(header["still"] and header["seq"] == 1 and header["encoding"] == "png", "still: %r" % header)
        expect(payload[:8] == b"\x89PNG\r\n\x1a\n", "the still is a PNG")
        await s.ack(header["frame"])
        # Flow control: 8 views without acks get at most 2 frames; acks let the latest through.
        for seq in range(2, 10):
            await s.view(seq, eye="%d,-12,8" % (seq - 6))
        got = []
        try:
            while True:
                got.append(await s.next_frame(timeout=3))
        except asyncio.TimeoutError:
            pass
        except SystemExit:
            pass
        expect(1 <= len(got) <= 2, "at most 2 frames unacknowledged, got %d" % len(got))
        expect(all(not h["still"] for h, _ in got), "no still while frames wait for acks")
        for h, _ in got:
            await s.ack(h["frame"])
        seqs = [h["seq"] for h, _ in got]
        if seqs[-1] != 9:
            header, _ = await s.next_frame()
            seqs.append(header["seq"])
            await s.ack(header["frame"])
        expect(seqs[-1] == 9, "the latest view wins: %r" % seqs)
        expect(len(seqs) <= 3, "older views are dropped: %r" % seqs)
        # A bad view: an error naming it, the stream stays open.
        await ws.send("not json")
        error = await s.next_text()
        expect(error["type"] == "error" and "JSON" in error["message"], "%r" % error)
        await s.view(20, eye="1,2")
        error = await s.next_text()
        expect(error["type"] == "error" and error.get("seq") == 20 and "eye" in error["message"], "%r" % error)
        await s.view(21, w=0)
        error = await s.next_text()
        expect(error.get("seq") == 21 and "'w'" in error["message"], "%r" % error)
        # ping / pong
        pong = await ws.ping(b"are you there")
        await asyncio.wait_for(pong, 5)
        await s.view(22, w=200, h=100)
        header, _ = await s.next_frame()
        while header["still"] and header["seq"] != 22:  # the still of view 9, at rest meanwhile
            await s.ack(header["frame"])
            header, _ = await s.next_frame()
        expect(header["seq"] == 22 and header["width"] == 200, "after errors the stream serves: %r" % header)
        await ws.close(1000)
        expect(ws.close_code == 1000, "the server answers a normal close with 1000: %r" % ws.close_code)


async def video(port, out, codec):
    async with websockets.connect(uri(port), subprotocols=["plantview.v1"], max_size=None) as ws:
        s = Stream(ws, out)
        await ws.send(json.dumps({"type": "hello", "codec": codec, "max_kbps": 8000}))
        ready = await s.next_text()
        expect(ready["type"] == "ready" and ready["codec"] == codec, "ready: %r" % ready)
        headers = []
        for seq in range(1, 7):
            await s.view(seq, eye="%g,-12,8" % (-6 + 0.3 * seq), w=320, h=180)
            header, payload = await s.next_frame()
            expect(header["encoding"] == codec and not header["still"], "a %s frame: %r" % (codec, header))
            expect(header["seq"] == seq and len(payload) > 0, "%r" % header)
            headers.append(header)
            await s.ack(header["frame"])
        expect(headers[0]["key"], "the first frame is a key frame")
        expect(not all(h["key"] for h in headers[1:]), "later frames are not all key frames")
        await ws.send(json.dumps({"type": "key"}))
        await s.view(7, eye="-4,-12,8")
        header, _ = await s.next_frame()
        expect(header["key"], "a key frame on demand: %r" % header)
        await s.ack(header["frame"])
        with open(os.path.join(out, "headers.json"), "w") as f:
            json.dump(headers + [header], f)
        ready = await s.next_frame(timeout=10)  # the still at rest
        expect(ready[0]["still"], "a still at rest: %r" % ready[0])


async def token(port, out, secret):
    # The token in a subprotocol.
    async with websockets.connect(uri(port), subprotocols=["plantview.v1", "plantview.token." + secret]) as ws:
        expect(ws.subprotocol == "plantview.v1", "only plantview.v1 is answered")
        s = Stream(ws, out)
        await s.view(1)
        header, _ = await s.next_frame()
        expect(header["seq"] == 1, "served with the token in a subprotocol")
        expect(s.texts and s.texts[0]["type"] == "ready", "ready before the first frame without hello")
    # A wrong one: 401 before the upgrade.
    try:
        async with websockets.connect(uri(port), subprotocols=["plantview.v1", "plantview.token.wrong"]):
            fail("a wrong token in the subprotocol was accepted")
    except websockets.exceptions.InvalidStatusCode as e:
        expect(e.status_code == 401, "a wrong token: 401, got %d" % e.status_code)
    # The token in hello.
    async with websockets.connect(uri(port), subprotocols=["plantview.v1"]) as ws:
        s = Stream(ws, out)
        await ws.send(json.dumps({"type": "hello", "token": secret}))
        expect((await s.next_text())["type"] == "ready", "ready after hello with the token")
        await s.view(1)
        header, _ = await s.next_frame()
        expect(header["seq"] == 1, "served with the token in hello")
    for first in [json.dumps({"type": "hello", "token": "wrong"}),
                  json.dumps({"type": "view", "seq": 1, "params": VIEW})]:
        async with websockets.connect(uri(port)) as ws:
            await ws.send(first)
            try:
                await asyncio.wait_for(ws.recv(), 10)
                fail("served without the token")
            except websockets.exceptions.ConnectionClosed:
                pass
            expect(ws.close_code == 1008, "no or a wrong token: 1008, got %r" % ws.close_code)


def main():
    port, scenario, out = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    os.makedirs(out, exist_ok=True)
    extra = sys.argv[4] if len(sys.argv) > 4 else ""
    if scenario == "jpeg":
        asyncio.run(jpeg(port, out, extra))
    elif scenario in ("h264", "vp8"):
        asyncio.run(video(port, out, scenario))
    elif scenario == "token":
        asyncio.run(token(port, out, extra))
    else:
        fail("unknown scenario " + scenario)
    print("ok", flush=True)


if __name__ == "__main__":
    main()
