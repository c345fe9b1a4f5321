// A Foxglove WebSocket client for the viewer tests: @foxglove/ws-protocol's FoxgloveClient
// (the protocol implementation Foxglove's own tools use) over the `ws` package, with
// protobufjs decoding messages from the schemas the server advertises. Nothing here is ours
// but the bookkeeping: it prints one JSON object on stdout when done.
//
//   node client.js --url ws://127.0.0.1:8765 --seconds 10 --subscribe /tf,/scene \
//        [--dump /tf] [--clients N] [--garbage] [--reconnect]
//
// --dump TOPICS   decoded messages of these topics are printed in full (others: count, last)
// --clients N     N simultaneous connections, each subscribing (counts per client)
// --garbage       first send a non-JSON text frame, a binary frame with an unknown opcode,
//                 a subscribe to an unknown channel id and an unknown op, then carry on
// --reconnect     connect, receive for half the time, close, connect again for the rest
// --scene         keep the 3D scene as a client holds it (SceneUpdate deletions applied,
//                 entities replaced by id): `scene` (id -> entity) and `sceneHistory`, the
//                 sorted ids after each update that changed them
// --points        keep the polylines' points (default: their count only)
// SIGTERM or SIGINT ends every session at once and prints what was seen
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");
const protobuf = require("protobufjs");
const descriptor = require("protobufjs/ext/descriptor");

function parseArgs(argv) {
  const a = { url: "ws://127.0.0.1:8765", seconds: 5, subscribe: [], dump: [], clients: 1,
    garbage: false, reconnect: false, scene: false, points: false };
  for (let i = 2; i < argv.length; i++) {
    const k = argv[i];
    if (k === "--url") a.url = argv[++i];
    else if (k === "--seconds") a.seconds = Number(argv[++i]);
    else if (k === "--subscribe") a.subscribe = argv[++i].split(",").filter(Boolean);
    else if (k === "--dump") a.dump = argv[++i].split(",").filter(Boolean);
    else if (k === "--clients") a.clients = Number(argv[++i]);
    else if (k === "--garbage") a.garbage = true;
    else if (k === "--reconnect") a.reconnect = true;
    else if (k === "--scene") a.scene = true;
    else if (k === "--points") a.points = true;
    else throw new Error(`unknown argument ${k}`);
  }
  return a;
}

function decoderFor(channel) {
  if (channel.encoding === "protobuf") {
    const bytes = Buffer.from(channel.schema, "base64");
    const set = descriptor.FileDescriptorSet.decode(bytes);
    const root = protobuf.Root.fromDescriptor(set);
    const type = root.lookupType(channel.schemaName);
    return (data) => type.toObject(type.decode(data),
      { longs: Number, enums: String, defaults: true });
  }
  if (channel.encoding === "json") {
    const td = new TextDecoder();
    return (data) => JSON.parse(td.decode(data));
  }
  return () => null;
}

const stops = []; // a signal ends every open session

// The scene as a client keeps it: deletions first (by id, or all), then entities by id.
function applyScene(seen, msg) {
  const before = Object.keys(seen.scene).sort().join(",");
  for (const d of msg.deletions || []) {
    if (d.type === "MATCHING_ID") delete seen.scene[d.id];
    else seen.scene = {};
  }
  for (const e of msg.entities || []) seen.scene[e.id] = e;
  const ids = Object.keys(seen.scene).sort();
  if (ids.join(",") !== before) seen.sceneHistory.push(ids);
}

// One connection: resolves with what it saw when `seconds` are up.
function session(args, seconds, label) {
  return new Promise((resolve) => {
    const seen = { label, protocol: null, channels: [], counts: {}, dumped: {}, last: {},
      errors: [], statuses: [], opened: false, scene: {}, sceneHistory: [] };
    const ws = new WebSocket(args.url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL, "foxglove.sdk.v1"]);
    const client = new FoxgloveClient({ ws });
    const subs = new Map(); // subscription id -> {topic, decode}
    client.on("open", () => {
      seen.opened = true;
      seen.protocol = ws.protocol;
      if (args.garbage) {
        ws.send("this is not json {");
        ws.send(Buffer.from([0x7f, 1, 2, 3, 4]));
        ws.send(JSON.stringify({ op: "subscribe",
          subscriptions: [{ id: 4242, channelId: 987654 }] }));
        ws.send(JSON.stringify({ op: "noSuchOp", x: 1 }));
      }
    });
    client.on("error", (e) => seen.errors.push(String(e && e.message ? e.message : e)));
    client.on("status", (s) => seen.statuses.push(s.message));
    client.on("advertise", (channels) => {
      for (const ch of channels) {
        seen.channels.push({ id: ch.id, topic: ch.topic, encoding: ch.encoding,
          schemaName: ch.schemaName, schemaEncoding: ch.schemaEncoding });
        if (args.subscribe.includes(ch.topic) || args.subscribe.includes("*")) {
          const id = client.subscribe(ch.id);
          subs.set(id, { topic: ch.topic, decode: decoderFor(ch) });
        }
      }
    });
    client.on("message", ({ subscriptionId, data }) => {
      const sub = subs.get(subscriptionId);
      if (!sub) return;
      const t = sub.topic;
      seen.counts[t] = (seen.counts[t] || 0) + 1;
      let msg;
      try {
        msg = sub.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
      } catch (e) {
        seen.errors.push(`decode ${t}: ${e.message}`);
        return;
      }
      if (msg && msg.entities && !args.points) {  // the polylines' lengths, not points
        for (const e of msg.entities) for (const l of e.lines || []) l.points = l.points.length;
      }
      if (args.scene && msg && (msg.entities || msg.deletions)) applyScene(seen, msg);
      if (args.dump.includes(t)) (seen.dumped[t] = seen.dumped[t] || []).push(msg);
      else seen.last[t] = msg;
    });
    let done = false;
    const end = () => {
      if (done) return;
      done = true;
      ws.close();
      resolve(seen);
    };
    stops.push(end);
    setTimeout(end, seconds * 1000);
  });
}

for (const sig of ["SIGTERM", "SIGINT"]) process.on(sig, () => stops.forEach((end) => end()));

async function main() {
  const args = parseArgs(process.argv);
  let out;
  if (args.reconnect) {
    const first = await session(args, args.seconds / 2, "first");
    const second = await session(args, args.seconds / 2, "second");
    out = { sessions: [first, second] };
  } else {
    const all = [];
    for (let i = 0; i < args.clients; i++) all.push(session(args, args.seconds, `client${i}`));
    out = { sessions: await Promise.all(all) };
  }
  // exit only once the pipe has taken everything (a large result spans many writes)
  process.stdout.write(JSON.stringify(out) + "\n", () => process.exit(0));
}

main().catch((e) => {
  process.stderr.write(`client: ${e.stack || e}\n`);
  process.exit(1);
});
