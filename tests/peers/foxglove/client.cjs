// An independent Foxglove client (@foxglove/ws-protocol on foxglove.websocket.v1) for the
// tests: node client.cjs URL ROBOT TARGET. It subscribes to ROBOT's status and pose,
// calls /ROBOT/goto {"target": TARGET}, waits for the status to show the goal working,
// calls /ROBOT/stop, waits for the goal to end, then calls goto with a bad request.
// Each step is one JSON line on stdout; exit 0 when all happened, 2 after 60 s.
"use strict";
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, robot, targetText] = process.argv.slice(2);
const target = Number(targetText);
const say = (line) => process.stdout.write(JSON.stringify(line) + "\n");
const decoder = new TextDecoder();
const encoder = new TextEncoder();

const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const channels = new Map(); // topic -> channel
const subscriptions = new Map(); // subscription id -> topic
const services = new Map(); // name -> service
const calls = new Map(); // call id -> service name
let nextCall = 1;
let phase = "subscribing";
const seen = new Set();

setTimeout(() => {
  say({ step: "timeout", phase });
  process.exit(2);
}, 60000);

function call(name, request) {
  const service = services.get(`/${robot}/${name}`);
  const callId = nextCall++;
  calls.set(callId, name);
  client.sendServiceCallRequest({
    serviceId: service.id,
    callId,
    encoding: "json",
    data: encoder.encode(JSON.stringify(request)),
  });
}

function ready() {
  for (const topic of ["status", "pose"]) {
    const channel = channels.get(`/${robot}/${topic}`);
    if (channel && !seen.has(`sub:${topic}`)) {
      seen.add(`sub:${topic}`);
      subscriptions.set(client.subscribe(channel.id), topic);
    }
  }
}

client.on("open", () => say({ step: "open", protocol: ws.protocol }));
client.on("error", (error) => say({ step: "error", message: String(error) }));
client.on("serverInfo", (info) => say({ step: "serverInfo", capabilities: info.capabilities }));
client.on("advertise", (list) => {
  for (const channel of list) channels.set(channel.topic, channel);
  ready();
});
client.on("advertiseServices", (list) => {
  for (const service of list) services.set(service.name, service);
  say({ step: "services", names: list.map((service) => service.name).sort() });
});
client.on("message", ({ subscriptionId, data }) => {
  const topic = subscriptions.get(subscriptionId);
  if (!seen.has(`got:${topic}`)) {
    seen.add(`got:${topic}`);
    say({ step: "message", topic, bytes: data.byteLength });
  }
  if (topic !== "status") return;
  const status = JSON.parse(decoder.decode(data));
  if (phase === "subscribing" && seen.has("got:pose") && services.has(`/${robot}/goto`)) {
    phase = "goto";
    call("goto", { target });
  } else if (phase === "moving" && status.target_num_id === target && status.target_status === 1) {
    phase = "stop";
    say({ step: "working", target, x: status.current_pose_x, y: status.current_pose_y });
    call("stop", {});
  } else if (phase === "stopped" && status.target_status !== 1) {
    phase = "bad";
    say({ step: "ended", target_status: status.target_status });
    call("goto", { target: "three" });
  }
});
client.on("serviceCallResponse", ({ callId, data }) => {
  const name = calls.get(callId);
  say({ step: "response", service: name, answer: JSON.parse(decoder.decode(data)) });
  if (name === "goto" && phase === "goto") phase = "moving";
  if (name === "stop") phase = "stopped";
});
client.on("serviceCallFailure", ({ callId, message }) => {
  say({ step: "failure", service: calls.get(callId), message });
  if (phase === "bad") {
    client.close();
    process.exit(0);
  }
});
