// A remote agent server written from docs/remote_agent.md in Node.js, no npm packages: the same agent as
// examples/remote_agent_stdlib.py (habitat-baselines' GoalFollower idea on PointNav; forward and a left
// turn every fifth step on ObjectNav), for `navbench run --agent http://HOST:PORT`.
//
//   node examples/remote_agent_server.js --port 8765     # prints "listening on http://127.0.0.1:8765"
//   navbench check-agent http://127.0.0.1:8765
"use strict";
const http = require("http");

const PROTOCOL = "navbench-agent/1";
const [STOP, FORWARD, LEFT, RIGHT] = [0, 1, 2, 3];
const SIZES = { "<f4": 4, "<f8": 8, "<i4": 4, "<i8": 8, "|u1": 1 };

// uint32 LE N | N bytes of JSON header | arrays: the header (with `session`) and, per array, a view of its bytes.
function decodeArrays(body) {
  if (body.length < 4) throw new Error("body shorter than its 4-byte header length");
  const n = body.readUInt32LE(0);
  const header = JSON.parse(body.subarray(4, 4 + n).toString("utf8"));
  let offset = 4 + n;
  const arrays = {};
  for (const spec of header.arrays || []) {
    const itemsize = SIZES[spec.dtype];
    if (itemsize === undefined) throw new Error(`array ${spec.name}: unknown dtype ${spec.dtype}`);
    const size = spec.shape.reduce((a, b) => a * b, 1) * itemsize;
    if (offset + size > body.length) throw new Error(`array ${spec.name}: body ends before its ${size} bytes`);
    arrays[spec.name] = { dtype: spec.dtype, shape: spec.shape, bytes: body.subarray(offset, offset + size) };
    offset += size;
  }
  if (offset !== body.length) throw new Error(`${body.length - offset} bytes after the last array`);
  return [header, arrays];
}

class GoalFollower {
  constructor() { this.steps = 0; }
  reset(episode) { this.steps = 0; }
  act(arrays) {
    this.steps += 1;
    const goal = arrays.pointgoal_with_gps_compass;
    if (!goal) return this.steps % 5 === 0 ? LEFT : FORWARD;
    const rho = goal.bytes.readFloatLE(0), theta = goal.bytes.readFloatLE(4);
    if (rho < 0.2) return STOP;
    if (Math.abs(theta) < (15 * Math.PI) / 180) return FORWARD;
    return theta > 0 ? LEFT : RIGHT; // theta is counter-clockwise positive
  }
  log() { return { steps: this.steps }; }
}

const sessions = new Map();

function answer(res, status, payload) {
  const body = Buffer.from(JSON.stringify(payload));
  res.writeHead(status, { "Content-Type": "application/json", "Content-Length": body.length });
  res.end(body); // headers and body go out together
}

function handle(req, res, body) {
  if (req.method === "GET") {
    if (req.url !== "/info") return answer(res, 404, { error: `no such endpoint: GET ${req.url}` });
    return answer(res, 200, { protocol: PROTOCOL, name: "node-goal-follower", sensors: [], episode_log: true });
  }
  if (req.method !== "POST") return answer(res, 404, { error: `no such endpoint: ${req.method} ${req.url}` });
  let request, arrays;
  try {
    if (req.url === "/act") [request, arrays] = decodeArrays(body);
    else request = JSON.parse(body.length ? body.toString("utf8") : "{}");
    if (request === null || typeof request !== "object" || request.session === undefined) {
      throw new Error("no session");
    }
  } catch (err) {
    return answer(res, 400, { error: `bad request: ${String(err.message).split("\n")[0]}` });
  }
  const session = String(request.session);
  switch (req.url) {
    case "/reset": {
      if (!sessions.has(session)) sessions.set(session, new GoalFollower());
      sessions.get(session).reset(request.episode);
      return answer(res, 200, { ok: true });
    }
    case "/close":
      sessions.delete(session);
      return answer(res, 200, { ok: true });
    case "/act":
    case "/log": {
      const agent = sessions.get(session);
      if (!agent) return answer(res, 400, { error: `unknown session '${session}': POST /reset first` });
      return req.url === "/act" ? answer(res, 200, { action: agent.act(arrays) })
                                : answer(res, 200, { log: agent.log() });
    }
    default:
      return answer(res, 404, { error: `no such endpoint: POST ${req.url}` });
  }
}

const server = http.createServer((req, res) => {
  const chunks = [];
  req.on("data", (c) => chunks.push(c));
  req.on("end", () => handle(req, res, Buffer.concat(chunks)));
});
server.keepAliveTimeout = 600000; // one connection per client for the whole run
server.on("connection", (socket) => socket.setNoDelay(true)); // else Nagle + delayed ACK: ~40 ms a step

const args = process.argv.slice(2);
const opt = (name, fallback) => (args.includes(name) ? args[args.indexOf(name) + 1] : fallback);
const host = opt("--host", "127.0.0.1");
server.listen(Number(opt("--port", "8765")), host, () => {
  console.log(`listening on http://${host}:${server.address().port}`);
});
process.on("SIGTERM", () => process.exit(0));
