// An independent client of the frame stream (docs/stream.md) on npm's ws: handshake with the
// subprotocol, hello, a view, its JPEG frame, an ack, ping/pong and a normal close. Run by
// tests/test_stream.cpp: node stream_client.js PORT. Exits 0, or 1 with what was wrong.
'use strict';
const WebSocket = require('ws');

const port = Number(process.argv[2]);
const fail = (message) => { console.error('FAIL: ' + message); process.exit(1); };
const expect = (condition, message) => { if (!condition) fail(message); };
setTimeout(() => fail('timed out'), 30000).unref();

const ws = new WebSocket(`ws://127.0.0.1:${port}/api/stream`, ['plantview.v1']);
ws.binaryType = 'nodebuffer';
let step = 'ready';
ws.on('open', () => {
  expect(ws.protocol === 'plantview.v1', `subprotocol: ${ws.protocol}`);
  ws.send(JSON.stringify({ type: 'hello', codec: 'jpeg' }));
});
ws.on('message', (data, isBinary) => {
  if (!isBinary) {
    const message = JSON.parse(data.toString());
    if (step === 'ready') {
      expect(message.type === 'ready' && message.codec === 'jpeg' && message.protocol === 1, data.toString());
      step = 'frame';
      ws.send(JSON.stringify({ type: 'view', seq: 3, params: { eye: '-6,-12,8', target: '7.5,0,0', w: 128, h: 96 } }));
    }
    return;
  }
  if (step !== 'frame') return;  // the still at rest may follow
  expect(data.subarray(0, 4).toString() === 'PVF1', 'PVF1');
  const length = data.readUInt32LE(4);
  const header = JSON.parse(data.subarray(8, 8 + length).toString());
  const payload = data.subarray(8 + length);
  expect(header.seq === 3 && header.encoding === 'jpeg' && header.width === 128 && header.height === 96,
         JSON.stringify(header));
  expect(payload[0] === 0xff && payload[1] === 0xd8, 'a JPEG');
  ws.send(JSON.stringify({ type: 'ack', frame: header.frame }));
  step = 'pong';
  ws.ping(Buffer.from('node'));
});
ws.on('pong', (data) => {
  expect(step === 'pong' && data.toString() === 'node', 'pong');
  step = 'close';
  ws.close(1000, 'done');
});
ws.on('close', (code) => {
  expect(step === 'close' && code === 1000, `closed with ${code} at ${step}`);
  console.log('ok');
  process.exit(0);
});
ws.on('error', (e) => fail(String(e)));
