'use strict';
/*
 * VM host of vm_node_peer (node_peer.sh): node-canopen (npm `canopen` 6.2.1, pinned with
 * `socketcan` 4.0.7 in tests/vm/node_peer/package-lock.json), a CANopen implementation this
 * project did not write, as the upstream host of the built `oegw run` (vcan0) with `oegw-sim`
 * devices downstream (vcan1). It judges only what it sees on the buses; node_peer.sh judges
 * candump's recordings. One `oegw run` per cab, in turn: the demo cab (every part), a cab with
 * only joystick 2, one with only pedal 2, the full FE set (TPDOs only).
 *
 * Usage: node node_peer_host.js NODE_MODULES OEGW_SIM SOURCE_DIR RUN_DIR [PART...]
 *   RUN_DIR   holds <cab>.yaml and <cab>.eds (node_peer.sh writes them with `oegw eds`) for the
 *             cabs demo, joystick2, pedal2, full; the gateway's log goes to RUN_DIR/<cab>.log
 *   PART      cab names, or demo:<part> (tpdo sdo bound indication remote_faults emcy heartbeat
 *             sync nmt lss) to run a subset while debugging; default: everything
 * Prints one PASS/FAIL line per check; the exit status is the number of failures (at most 100).
 *
 * node-canopen's quirks (worked around here; oegw is not changed to suit them). Where it and oegw
 * disagree on the wire, CiA 301 decides
 * (docs/developer/vm-tier.md#vm_node_peer-node-canopen-against-oegw keeps the list): so far only
 * Q4, where oegw is right.
 *  Q1 Eds.load does not evaluate $NODEID (CiA 306 v1.3 lets a DefaultValue say "$NODEID+0x180",
 *     as `oegw eds` writes the COB-IDs): the text is substituted before loading (substituteNodeId).
 *  Q2 a DataObject's subIndex is read back from its key as hex, but the key is written in decimal
 *     (sub-index 10h is "sub16" and reads 16h): Eds.save writes sub-indices in decimal, and
 *     Eds.addReceivePdo writes wrong mapping entries for sub-indices 10h and above. The test
 *     writes the RPDO mapping entries itself (mirrorTpdo).
 *  Q3 Device.mapRemoteNode copies sub-indices 1..SubNumber-1 only, so an object with gaps (CiA
 *     852 Table 3's 6120h:81h..88h; CiA 306 numbers the sub-objects present, SubNumber counts
 *     them) loses its entries: the test maps the gateway's TPDOs itself (mirrorTpdo).
 *  Q4 an SDO abort from the server is answered with an abort frame of its own. CiA 301 §7.2.4.3.17:
 *     the abort transfer service is unconfirmed, and it ends the transfer on both sides, so nothing
 *     answers an abort; oegw is right to ignore the echo (node_peer.sh: no frame of the gateway
 *     follows one, and counts them).
 *  Q5 default time-outs (SDO 30 ms, LSS 20 ms) are too short for a TCG guest, and
 *     Lss.switchModeSelective without a time-out rejects at once: every call passes one.
 *  Q6 a Device's PDO module runs only while the Device itself is NMT operational (node-canopen 6):
 *     the peer starts itself.
 *  Q7 no LSS "identify non-configured remote slave": fastscan finds the node without node-ID.
 *  Q8 the client sends a value of 4 bytes or less expedited and one of more segmented: CiA 301
 *     §7.2.4.3.3 leaves the choice to the client, and no writable object here is longer than 4
 *     bytes, so for a segmented download the test swaps the client's initiate for the segmented
 *     one (size indicated) and node-canopen's own segment code carries the data (segmentedDownload).
 *  Q9 its heartbeat producer writes 1017h as UNSIGNED32 (CiA 301: UNSIGNED16); local only.
 *  Q10 Eds.load raises sub-index 00h of an array or record to the highest sub-index present, so a
 *     PDO mapping 1A00h with DefaultValue 5 and entries 01h..08h (CiA 306: the unused ones 0)
 *     reads 8: the test takes the number of mapped objects from sub-index 00h's DefaultValue.
 */
const fs = require('fs');
const path = require('path');
const { spawn } = require('child_process');
const { createRequire } = require('module');

const [nodeModules, simProgram, srcDir, runDir, ...partArgs] = process.argv.slice(2);
if (!runDir) {
  console.error('usage: node node_peer_host.js NODE_MODULES OEGW_SIM SOURCE_DIR RUN_DIR [PART...]');
  process.exit(64);
}
const req = createRequire(path.join(nodeModules, '..', 'package.json'));
const canopen = req('canopen');
const socketcan = req('socketcan');
const { Device, Eds, ObjectType, AccessType } = canopen;

const GW = 0x20;        // the gateway's node-ID (every fixture's upstream.node_id)
const PEER = 0x7d;      // node-canopen's node-ID upstream (its heartbeat, its SDO client)
const PEER_DOWN = 0x7c; // its node-ID downstream (LSS master, SDO client of a re-addressed node)
const SDO_MS = 3000;    // a remote transfer waits for the gateway's downstream time-out (500 ms)
const BOUND = { tx: 0x690, rx: 0x6b0 }; // vm_node_peer.yaml: SDO server 1201h bound to left_grip
const UP_NET = 1;
const DOWN_NET = 2;
const t0 = Date.now();
const elapsed = () => ((Date.now() - t0) / 1000).toFixed(1);
const hex = (v, w = 8) => (v >>> 0).toString(16).toUpperCase().padStart(w, '0') + 'h';
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

let passes = 0;
let fails = 0;
function check(ok, what) {
  console.log(`${ok ? 'PASS' : 'FAIL'} ${what}`);
  if (ok) passes++;
  else fails++;
  return ok;
}
const info = (what) => console.log(`  [${elapsed()} s] ${what}`);

// ---------------------------------------------------------------------------------------------
// The buses: node-canopen opens no socket; it emits {id, data} and takes frames by receive(). The
// socketcan addon's raw channel uses the same shape, so the bridge is a listener each way. Every
// frame is also logged with its arrival time for the checks (own frames are logged as sent: a raw
// socket does not receive its own frames).

class Bus {
  constructor(ifname, filters) {
    this.name = ifname;
    this.channel = socketcan.createRawChannel(ifname, true);
    if (filters) this.channel.setRxFilters(filters);
    this.log = [];
    this.waiters = [];
    this.devices = [];
    this.channel.addListener('onMessage', (m) => this._rx({ id: m.id, data: Buffer.from(m.data), t: Date.now() }));
    this.channel.start();
  }

  _rx(f) {
    this.log.push(f);
    for (const d of this.devices) d.device.receive({ id: f.id, data: f.data });
    this.waiters = this.waiters.filter((w) => !(w.pred(f) && (w.resolve(f), true)));
  }

  send(id, data) {
    this.channel.send({ id, ext: false, rtr: false, data });
    this.log.push({ id, data: Buffer.from(data), t: Date.now(), own: true });
  }

  attach(device) {
    const entry = { device, listener: (m) => this.send(m.id, m.data) };
    device.on('message', entry.listener);
    this.devices.push(entry);
  }

  detach(device) {
    const entry = this.devices.find((e) => e.device === device);
    if (!entry) return;
    device.removeListener('message', entry.listener);
    this.devices = this.devices.filter((e) => e !== entry);
    device.stop();
  }

  mark() {
    return this.log.length;
  }

  // Frames received since mark `from` that satisfy pred.
  since(from, pred = () => true) {
    return this.log.slice(from).filter((f) => !f.own && pred(f));
  }

  // The first frame from mark `from` on (already logged or still to come) that satisfies pred, or
  // null after timeoutMs.
  wait(pred, timeoutMs, from = this.log.length) {
    const seen = this.log.slice(from).find((f) => !f.own && pred(f));
    if (seen) return Promise.resolve(seen);
    return new Promise((resolve) => {
      const w = { pred, resolve: (f) => { clearTimeout(timer); resolve(f); } };
      const timer = setTimeout(() => {
        this.waiters = this.waiters.filter((x) => x !== w);
        resolve(null);
      }, timeoutMs);
      this.waiters.push(w);
    });
  }
}

const frameIs = (id, bytes) => (f) => f.id === id && bytes.every((b, i) => b === null || f.data[i] === b);
const frameText = (f) => (f ? `${f.id.toString(16).toUpperCase().padStart(3, '0')}#${f.data.toString('hex').toUpperCase()}` : 'none');

// Raw sockets bound to an interface, as lib.sh's can_receivers counts them.
function canReceivers(dev) {
  let n = 0;
  for (const f of fs.readdirSync('/proc/net/can').filter((x) => x.startsWith('rcvlist_'))) {
    for (const line of fs.readFileSync(`/proc/net/can/${f}`, 'utf8').split('\n'))
      if (line.trim().split(/\s+/)[0] === dev) n++;
  }
  return n;
}

async function until(cond, timeoutMs, stepMs = 50) {
  const end = Date.now() + timeoutMs;
  for (;;) {
    const v = await cond();
    if (v) return v;
    if (Date.now() > end) return null;
    await sleep(stepMs);
  }
}

// ---------------------------------------------------------------------------------------------
// Processes: one `oegw-sim --commands` process per cab (its replies are the lines it prints), one
// `oegw run` per cab.

class Sim {
  constructor(specs, logFile) {
    this.proc = spawn(simProgram, ['-i', 'vcan1', '--commands', ...specs], { stdio: ['pipe', 'pipe', 'pipe'] });
    this.replies = [];
    this.pending = [];
    this.buffer = '';
    const log = fs.createWriteStream(logFile);
    this.proc.stderr.pipe(log);
    this.exited = new Promise((r) => this.proc.on('exit', (code, sig) => r(code ?? sig)));
    this.proc.stdout.on('data', (d) => {
      this.buffer += d.toString();
      let nl;
      while ((nl = this.buffer.indexOf('\n')) >= 0) {
        const line = this.buffer.slice(0, nl);
        this.buffer = this.buffer.slice(nl + 1);
        log.write(`reply: ${line}\n`);
        const p = this.pending.shift();
        if (p) p(line);
      }
    });
  }

  // One command line; resolves with its reply (oegw-sim answers every line, in order).
  command(line) {
    return new Promise((resolve) => {
      this.pending.push(resolve);
      this.proc.stdin.write(line + '\n');
    });
  }

  async commands(lines) {
    const replies = await Promise.all(lines.map((l) => this.command(l)));
    const bad = replies.filter((r) => !r.startsWith('ok'));
    if (bad.length) throw new Error(`oegw-sim refused: ${bad.join('; ')}`);
  }

  async stop() {
    this.proc.stdin.end();  // the end of its command stream ends oegw-sim
    const t = setTimeout(() => this.proc.kill('SIGKILL'), 5000);
    await this.exited;
    clearTimeout(t);
  }
}

class Gateway {
  constructor(yaml, logFile) {
    const oegw = path.join(path.dirname(simProgram), 'oegw');
    const out = fs.openSync(logFile, 'w');
    this.proc = spawn(oegw, ['run', yaml], { stdio: ['ignore', out, out] });
    this.exited = new Promise((r) => this.proc.on('exit', (code, sig) => r(code ?? sig)));
  }

  signal(sig) {
    this.proc.kill(sig);
  }

  async stop() {
    this.proc.kill('SIGTERM');
    const t = setTimeout(() => this.proc.kill('SIGKILL'), 10000);
    const rc = await this.exited;
    clearTimeout(t);
    return rc;
  }
}

// ---------------------------------------------------------------------------------------------
// The EDS `oegw eds` wrote, as node-canopen reads it.

// Q1: "$NODEID+<n>" (CiA 306) evaluated for node `id`.
function substituteNodeId(text, id) {
  return text.replace(/\$NODEID\s*\+\s*(0x[0-9A-Fa-f]+|\d+)/g, (m, v) => '0x' + (id + Number(v)).toString(16).toUpperCase());
}

function loadEds(file) {
  const text = substituteNodeId(fs.readFileSync(file, 'utf8'), GW);
  const tmp = path.join('/tmp', path.basename(file, '.eds') + '.node.eds');
  fs.writeFileSync(tmp, text);
  return Eds.fromFile(tmp);
}

// The TPDOs the EDS declares: {n, comm, map} for every 1800h..19FFh present.
function declaredTpdos(eds) {
  const out = [];
  for (let n = 1; n <= 512; n++) {
    const comm = eds.getEntry(0x1800 + n - 1);
    if (comm) out.push({ n, comm, map: eds.getEntry(0x1a00 + n - 1) });
  }
  return out;
}

// TPDO n's COB-ID for the test: TPDO 1 its predefined 180h + node-ID, the others 340h + n
// (341h..369h: free on this bus, outside CiA 301 §7.3.5's restricted identifiers).
const tpdoCobId = (n) => (n === 1 ? 0x180 + GW : 0x340 + n);

// The mapping entries of TPDO n as the EDS gives them: sub-index 0's DefaultValue of them (Q10),
// each read from its raw mapping value (Q2: never from DataObject.subIndex).
function mappedEntries(eds, n) {
  const map = eds.getEntry(0x1a00 + n - 1);
  const out = [];
  for (let i = 1; i <= Number(map.at(0).defaultValue); i++) {
    const v = map[i].value >>> 0;
    out.push({ index: v >>> 16, sub: (v >>> 8) & 0xff, bits: v & 0xff });
  }
  return out;
}

// The peer's own copy of a mapped object (same index, every sub-index the gateway's EDS has, its
// data types), so that node-canopen decodes the PDO bytes by the EDS's types (Q3: not
// mapRemoteNode).
function mirrorObject(peerEds, gwEds, index) {
  if (peerEds.getEntry(index)) return;
  const src = gwEds.getEntry(index);
  peerEds.addEntry(index, { parameterName: src.parameterName, objectType: ObjectType.ARRAY });
  for (let s = 1; s <= 0xfe; s++) {
    const sub = src.at(s);
    if (!sub) continue;
    peerEds.addSubEntry(index, s, {
      parameterName: sub.parameterName, dataType: sub.dataType, accessType: AccessType.READ_WRITE,
      defaultValue: 0, pdoMapping: true,
    });
  }
}

// An RPDO of the peer on TPDO n's COB-ID, mapping the peer's copies of the same objects (Q2: its
// mapping entries written after Eds.addReceivePdo, before the PDO module starts).
function mirrorTpdo(peerEds, gwEds, n) {
  const entries = mappedEntries(gwEds, n);
  for (const e of entries) mirrorObject(peerEds, gwEds, e.index);
  const cobId = tpdoCobId(n);
  peerEds.addReceivePdo({ cobId, transmissionType: 0xff, dataObjects: entries.map((e) => peerEds.getSubEntry(e.index, e.sub)) });
  for (let i = 0x1400; i <= 0x15ff; i++) {
    const comm = peerEds.getEntry(i);
    if (!comm || comm[1].value !== cobId) continue;
    const map = peerEds.getEntry(i + 0x200);
    entries.forEach((e, k) => { map[k + 1].value = ((e.index << 16) | (e.sub << 8) | e.bits) >>> 0; });
  }
  return { n, cobId, entries, bytes: entries.reduce((s, e) => s + e.bits, 0) / 8 };
}

// ---------------------------------------------------------------------------------------------
// The host: node-canopen's Device on vcan0 with an SDO client of the gateway (default channel and
// the bound channel), a heartbeat consumer and an EMCY consumer of it.

class Host {
  constructor(bus, gwEds) {
    this.bus = bus;
    this.gwEds = gwEds;
    this.device = new Device({ id: PEER });
    const eds = this.device.eds;
    eds.addSdoClientParameter(GW, 0x600 + GW, 0x580 + GW);
    eds.addSdoClientParameter(GW, BOUND.tx, BOUND.rx);  // its second SDO client parameter, custom COB-IDs
    this.consumerMs = 3 * gwEds.getHeartbeatProducerTime();
    eds.addHeartbeatConsumer(GW, this.consumerMs);
    eds.addEmcyConsumer(gwEds.getEmcyCobId());
    this.emcys = [];
    this.heartbeats = [];
    this.timeouts = [];
    this.device.emcy.on('emergency', ({ cobId, em }) => this.emcys.push({ cobId, code: em.code, register: em.register, info: Buffer.from(em.info), t: Date.now() }));
    this.device.nmt.on('heartbeat', ({ deviceId, state }) => this.heartbeats.push({ deviceId, state, t: Date.now() }));
    this.device.nmt.on('timeout', (deviceId) => this.timeouts.push({ deviceId, t: Date.now() }));
    this.tpdos = [];
    bus.attach(this.device);
    this.device.start();  // pre-operational: SDO client, EMCY and heartbeat consumers; no PDO yet
  }

  // Q6: once its RPDOs exist, the peer sets itself operational, which starts its PDO module.
  operational() {
    this.device.nmt.startNode();
  }

  stop() {
    this.bus.detach(this.device);
  }

  get sdo() {
    return this.device.sdo;
  }

  upload(index, subIndex, opts = {}) {
    return this.sdo.upload({ deviceId: GW, index, subIndex, timeout: SDO_MS, ...opts });
  }

  download(index, subIndex, data, opts = {}) {
    return this.sdo.download({ deviceId: GW, index, subIndex, data, timeout: SDO_MS, ...opts });
  }

  async u32(index, subIndex, opts) {
    const b = await this.upload(index, subIndex, opts);
    return Buffer.concat([b, Buffer.alloc(4)]).readUInt32LE(0);
  }

  // The abort code a transfer ended with, or null when it succeeded.
  async abortOf(promise) {
    try {
      await promise;
      return null;
    } catch (e) {
      return e.code === undefined ? `${e.message}` : e.code >>> 0;
    }
  }

  emcysSince(t, pred = () => true) {
    return this.emcys.filter((e) => e.t >= t && pred(e));
  }

  waitEmcy(pred, timeoutMs, since = Date.now()) {
    return until(() => this.emcysSince(since, pred)[0], timeoutMs);
  }

  // The gateway's error register as its last EMCY gave it (every raise and clear sends one).
  lastRegister() {
    return this.emcys.length ? this.emcys[this.emcys.length - 1].register : 0;
  }

  waitHeartbeat(state, timeoutMs, since = Date.now()) {
    return until(() => this.heartbeats.find((h) => h.t >= since && h.deviceId === GW && h.state === state), timeoutMs);
  }

  value(index, sub) {
    return this.device.eds.getSubEntry(index, sub).value;
  }
}

const u16 = (v) => { const b = Buffer.alloc(2); b.writeUInt16LE(v); return b; };
const u32b = (v) => { const b = Buffer.alloc(4); b.writeUInt32LE(v >>> 0); return b; };

// Q8: a segmented download of a value of 4 bytes or less, by node-canopen's own segment code.
async function segmentedDownload(host, index, subIndex, data, opts = {}) {
  const sdo = host.sdo;
  const own = sdo._downloadStart;
  sdo._downloadStart = function initiateSegmented(transfer) {
    const b = Buffer.alloc(8);
    b[0] = 0x21;  // download initiate, segmented, size indicated (CiA 301 §7.2.4.3.3)
    b.writeUInt16LE(transfer.index, 1);
    b[3] = transfer.subIndex || 0;
    b.writeUInt32LE(transfer.data.length, 4);
    transfer.size = Infinity;  // its initiate answer handler ends a transfer of size <= 4 as expedited
    this.send(transfer.cobId, b);
  };
  try {
    await host.download(index, subIndex, data, opts);
  } finally {
    sdo._downloadStart = own;
  }
}

// An UNSIGNED16 written in each transfer type — expedited, segmented (Q8), block — and read back
// after each (by expedited upload; the block download's by block upload).
async function downloadEachWay(h, where, index, [expedited, segmented, block], opts = {}) {
  const name = hex(index, 4);
  const back = async (o = opts) => (await h.upload(index, 0, o)).readUInt16LE(0);
  await h.download(index, 0, u16(expedited), opts);
  check((await back()) === expedited, `${where}: expedited download of ${name} = ${expedited}, read back`);
  await segmentedDownload(h, index, 0, u16(segmented), opts);
  check((await back()) === segmented, `${where}: segmented download of ${name} = ${segmented} (Q8), read back`);
  await h.download(index, 0, u16(block), { ...opts, blockTransfer: true });
  const got = await back({ ...opts, blockTransfer: true });
  check(got === block, `${where}: block download of ${name} = ${block}, read back by block upload (${got})`);
}

// A VISIBLE_STRING read by segmented and by block upload.
async function uploadStringEachWay(h, where, index, want, opts = {}) {
  const str = (b) => b.toString('latin1').replace(/\0+$/, '');
  const seg = str(await h.upload(index, 0, opts));
  check(seg === want, `${where}: segmented upload of ${hex(index, 4)} = "${seg}"`);
  const blk = str(await h.upload(index, 0, { ...opts, blockTransfer: true }));
  check(blk === want, `${where}: block upload of ${hex(index, 4)} = "${blk}"`);
}

// ---------------------------------------------------------------------------------------------
// The cabs: the oegw-sim devices and, for every FE field the mapping file feeds, the object it
// lands in (CiA 852 clause 9: Table 1 joystick n 6000h:2n-1 memory, 6000h:2n buttons, 6401h:3n-2..3n
// x, y, z; Table 2 pedal n 6000h:20h+n memory, 6401h:30h+n; Table 3 encoder n 6120h:80h+n;
// Table 4 wheel n 6401h:40h+n; Table 5 button cluster n 6000h:31h+8(n-1).., eight switches a
// byte) and how a signal value becomes that object's value
// (docs/reference/mapping-file.md#translation-translatehpp: invert, deadband, scale with halves
// away from zero, clamp; a percent signal has 100 % = 32767).
const at = {
  buttons: (n) => [0x6000, 2 * n],
  axis: (n, a) => [0x6401, 3 * (n - 1) + 1 + a],
  pedal: (n) => [0x6401, 0x30 + n],
  encoder: (n) => [0x6120, 0x80 + n],
  wheel: (n) => [0x6401, 0x40 + n],
  switches: (n, k) => [0x6000, 0x31 + 8 * (n - 1) + k],
};
const roundAway = (x) => Math.sign(x) * Math.floor(Math.abs(x) + 0.5);
const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
const conv = {
  percent: (db) => (v) => (Math.abs(v) <= db ? 0 : clamp(roundAway((v * 32767) / 100), -32767, 32767)),
  raw16: (db, { invert = false, lo = -32768, hi = 32767 } = {}) => (v) => {
    const s = invert ? -v : v;
    return Math.abs(s) <= db ? 0 : clamp(s, lo, hi);
  },
  u32: () => (v) => v >>> 0,
  byte: () => (v) => v & 0xff,
};

// Device kinds: their oegw-sim spec and the signal values of value set k for the i-th device.
// An elobau grip as oegw-sim makes it has buttons 1..6 fitted (2100h:01h = 3Fh, the document's
// default): buttons 7 and 8 are NotAvailable, so the cabs map and press only 1..6. The MCB-402 is
// wired as vm_node_peer.yaml's button_bits say (the simulator's default is the table's other
// reading, docs/design/device-documents.md#corners-every-reading-a-document-permits).
const kinds = {
  grip: {
    spec: (name, node) => `elobau-mfg:${node}:name=${name}`,
    values: (i, k) => ({ x: [35 + 3 * i, -(50 + 2 * i)][k], y: [-(20 + i), 45 + 2 * i][k], wheel_a: [60 - 2 * i, -(25 + i)][k], pressed: ((i + 3 * k) % 6) + 1, buttons: 6 }),
  },
  mcb402: {
    spec: (name, node) => `mcb402:${node}:name=${name},wiring=1/2/3/4/5/7/6`,
    values: (i, k) => ({ x: [12000, -9000][k], y: [-5000, 31000][k], z: [20000, -32768][k], pressed: [1, 6][k], buttons: 7 }),
  },
  pedal: {
    spec: (name, node) => `cia401:${node}:name=${name},eds=${srcDir}/subdevices/eds/generic_pedal.eds`,
    values: (i, k) => ({ 'analog[1]': [1000 + 500 * i, 9000 + 400 * i][k] }),
  },
  encoder: {
    spec: (name, node) => `novotechnik-406:${node}:name=${name}`,
    values: (i, k) => ({ position: [100000 + 12345 * i, 7654321 + 1000 * i][k] }),
  },
  cluster: {
    spec: (name, node) => `cia401:${node}:name=${name},eds=${srcDir}/subdevices/eds/button_cluster.eds`,
    values: (i, k) => ({ 'in[1]': [0xa5 ^ i, 0x3c ^ i][k], 'in[2]': [0x0f + i, 0xf0 - i][k] }),
  },
};

// fields: [object, device name, signal, conversion]; button bytes: [object, device name, 'buttons'].
function cab(name, devices, fields) {
  return { name, devices, fields, nodes: devices.map((d) => d.node) };
}

const cabs = {
  demo: cab('demo', [
    { name: 'right_grip', kind: 'grip', node: 0x11 }, { name: 'left_grip', kind: 'mcb402', node: 0x03 },
    { name: 'pedal', kind: 'pedal', node: 0x30 }, { name: 'seat_knob', kind: 'encoder', node: 0x7f },
    { name: 'cluster', kind: 'cluster', node: 0x31 },
  ], [
    [at.axis(1, 0), 'right_grip', 'x', conv.percent(2)], [at.axis(1, 1), 'right_grip', 'y', conv.percent(2)],
    [at.buttons(1), 'right_grip', 'buttons'], [at.wheel(1), 'right_grip', 'wheel_a', conv.percent(2)],
    [at.axis(2, 0), 'left_grip', 'x', conv.raw16(300)], [at.axis(2, 1), 'left_grip', 'y', conv.raw16(300, { invert: true })],
    [at.axis(2, 2), 'left_grip', 'z', conv.raw16(300, { lo: -32767, hi: 32767 })], [at.buttons(2), 'left_grip', 'buttons'],
    [at.pedal(1), 'pedal', 'analog[1]', conv.raw16(100)], [at.encoder(1), 'seat_knob', 'position', conv.u32()],
    [at.switches(1, 0), 'cluster', 'in[1]', conv.byte()],
  ]),
  joystick2: cab('joystick2', [{ name: 'left_grip', kind: 'grip', node: 0x11 }], [
    [at.axis(2, 0), 'left_grip', 'x', conv.percent(2)], [at.axis(2, 1), 'left_grip', 'y', conv.percent(2)],
    [at.buttons(2), 'left_grip', 'buttons'],
  ]),
  pedal2: cab('pedal2', [{ name: 'pedal', kind: 'pedal', node: 0x30 }], [[at.pedal(2), 'pedal', 'analog[1]', conv.raw16(100)]]),
  // tests/fixtures/full_fe_set.yaml: grips 11h..20h on joysticks 1..16 (wheels 1..8 from grips
  // 1..8), pedals 30h..3Fh, encoders 40h..47h, clusters 50h..57h (switch[1..16] <- in[1..2]).
  full: (() => {
    const devices = [];
    const fields = [];
    for (let n = 1; n <= 16; n++) {
      devices.push({ name: `grip${n}`, kind: 'grip', node: 0x10 + n });
      fields.push([at.axis(n, 0), `grip${n}`, 'x', conv.percent(2)], [at.axis(n, 1), `grip${n}`, 'y', conv.percent(2)], [at.buttons(n), `grip${n}`, 'buttons']);
      if (n <= 8) fields.push([at.wheel(n), `grip${n}`, 'wheel_a', conv.percent(2)]);
    }
    for (let n = 1; n <= 16; n++) {
      devices.push({ name: `pedal${n}`, kind: 'pedal', node: 0x2f + n });
      fields.push([at.pedal(n), `pedal${n}`, 'analog[1]', conv.raw16(100)]);
    }
    for (let n = 1; n <= 8; n++) {
      devices.push({ name: `enc${n}`, kind: 'encoder', node: 0x3f + n });
      fields.push([at.encoder(n), `enc${n}`, 'position', conv.u32()]);
    }
    for (let n = 1; n <= 8; n++) {
      devices.push({ name: `cluster${n}`, kind: 'cluster', node: 0x4f + n });
      fields.push([at.switches(n, 0), `cluster${n}`, 'in[1]', conv.byte()], [at.switches(n, 1), `cluster${n}`, 'in[2]', conv.byte()]);
    }
    return cab('full', devices, fields);
  })(),
};

// Value set k (0, 1; null: every signal at 0, no button pressed): the oegw-sim commands and the
// object values they must give (every mapped object not fed by a field reads 0:
// docs/design/cia852-decisions.md, Tables 1–7, entries of unconfigured instances).
function valueSet(c, k) {
  const lines = [];
  const signal = {};
  c.devices.forEach((d, i) => {
    const v = kinds[d.kind].values(i, k ?? 0);
    if (k === null) for (const s of Object.keys(v)) if (s !== 'buttons') v[s] = 0;
    for (const [s, x] of Object.entries(v)) {
      if (s === 'pressed' || s === 'buttons') continue;
      lines.push(`${d.name} ${s} ${x}`);
      signal[`${d.name}.${s}`] = x;
    }
    if (v.buttons) {
      for (let b = 1; b <= v.buttons; b++) lines.push(`${d.name} buttons[${b}] ${b === v.pressed ? 1 : 0}`);
      signal[`${d.name}.buttons`] = v.pressed ? 1 << (v.pressed - 1) : 0;
    }
  });
  const expect = new Map();
  for (const [[index, sub], dev, sig, f] of c.fields) {
    const x = signal[`${dev}.${sig}`];
    expect.set(`${index}:${sub}`, sig === 'buttons' ? x : f(x));
  }
  return { lines, expect };
}

// ---------------------------------------------------------------------------------------------
// One cab: the simulator, the gateway, the host, the TPDOs.

class Run {
  constructor(c, up, down) {
    this.cab = c;
    this.up = up;
    this.down = down;
    this.gwEds = loadEds(path.join(runDir, `${c.name}.eds`));
  }

  async start() {
    const c = this.cab;
    const before = canReceivers('vcan1');
    this.sim = new Sim(c.devices.map((d) => kinds[d.kind].spec(d.name, '0x' + d.node.toString(16))), path.join(runDir, `${c.name}-sim.log`));
    if (!(await until(() => canReceivers('vcan1') > before, 20000))) throw new Error('oegw-sim did not bind vcan1');
    this.host = new Host(this.up, this.gwEds);
    this.upMark = this.up.mark();
    this.downMark = this.down.mark();
    this.gateway = new Gateway(path.join(runDir, `${c.name}.yaml`), path.join(runDir, `${c.name}.log`));
    const boot = await this.up.wait(frameIs(0x700 + GW, [0x00]), 30000, this.upMark);
    check(boot !== null, `${c.name}: the gateway's boot-up 720h#00 seen after ${elapsed()} s`);
    if (!boot) throw new Error('no boot-up');
  }

  // Every sub-device of the cab started by the gateway (000h#01 node, or all): it sends that once
  // it has configured the node. Only NMT is read here: the full set's 240 heartbeats a second
  // would overflow this process's socket in a loaded guest (candump has the rest).
  async subdevicesStarted(timeoutMs) {
    const notStarted = () => {
      const started = new Set();
      for (const f of this.down.since(this.downMark, (x) => x.id === 0 && x.data[0] === 0x01))
        for (const n of f.data[1] === 0 ? this.cab.nodes : [f.data[1]]) started.add(n);
      return this.cab.nodes.filter((n) => !started.has(n));
    };
    await until(() => notStarted().length === 0, timeoutMs, 250);
    const left = notStarted();
    if (left.length) info(`no NMT start seen for ${left.map((n) => hex(n, 2)).join(' ')}`);
    return left.length === 0;
  }

  async stop() {
    if (this.host) this.host.stop();
    const rc = this.gateway ? await this.gateway.stop() : 'not started';
    if (this.sim) await this.sim.stop();
    check(rc === 0, `${this.cab.name}: SIGTERM ends oegw run with exit 0 (got ${rc})`);
  }

  // 1000h and 1018h:01..04 as the EDS gives them (expedited uploads).
  async identity() {
    const h = this.host;
    const want = [[0x1000, 0], [0x1018, 1], [0x1018, 2], [0x1018, 3], [0x1018, 4]];
    const bad = [];
    for (const [i, s] of want) {
      const eds = s ? this.gwEds.getSubEntry(i, s).value : this.gwEds.getEntry(i).value;
      const got = await h.u32(i, s);
      if (got !== eds >>> 0) bad.push(`${hex(i, 4)}:${s} ${hex(got)} (EDS ${hex(eds)})`);
    }
    check(bad.length === 0, `${this.cab.name}: 1000h and 1018h:01..04 read by SDO (expedited) equal the EDS's DefaultValues ${bad.join(', ')}`);
  }

  // Every TPDO the EDS declares: its COB-ID written by SDO (valid), the same COB-ID in an RPDO of
  // the peer mapping the EDS's mapping; 6423h TRUE (CiA 852 §8.6, CiA 401: analogue inputs send
  // on change only then).
  async enableTpdos() {
    const h = this.host;
    const declared = declaredTpdos(this.gwEds);
    const refused = [];
    for (const { n } of declared) {
      const code = await h.abortOf(h.download(0x1800 + n - 1, 1, u32b(tpdoCobId(n))));
      if (code !== null) refused.push(`TPDO ${n}: ${typeof code === 'number' ? hex(code) : code}`);
    }
    check(refused.length === 0, `${this.cab.name}: ${declared.length} TPDOs declared by the EDS, each given a valid COB-ID by SDO ${refused.join(', ')}`);
    const code = await h.abortOf(h.download(0x6423, 0, Buffer.from([1])));
    check(code === null, `${this.cab.name}: 6423h = TRUE (abort ${code})`);
    h.tpdos = declared.map(({ n }) => mirrorTpdo(h.device.eds, this.gwEds, n));
    h.operational();
    return declared.length;
  }

  // Waits until every object the cab's TPDOs map holds its expected value; the mismatches left.
  async converge(expect, timeoutMs) {
    const h = this.host;
    const mismatches = () => {
      const out = [];
      for (const t of h.tpdos) {
        for (const e of t.entries) {
          const want = expect.get(`${e.index}:${e.sub}`) ?? 0;
          const got = h.value(e.index, e.sub);
          if (got !== want) out.push(`TPDO ${t.n} ${hex(e.index, 4)}:${hex(e.sub, 2)} = ${got}, expected ${want}`);
        }
      }
      return out;
    };
    await until(() => mismatches().length === 0, timeoutMs, 100);
    return mismatches();
  }

  // NMT start, then two value sets of the simulated operator, each decoded from every TPDO.
  async tpdoCheck() {
    const c = this.cab;
    const n = await this.enableTpdos();
    const up = await this.subdevicesStarted(c.name === 'full' ? 90000 : 30000);
    check(up, `${c.name}: every sub-device (${c.nodes.length}) started by the gateway on vcan1 after ${elapsed()} s`);
    const from = this.up.mark();
    this.host.device.nmt.startNode(GW);
    check(await this.host.waitHeartbeat(0x05, 5000), `${c.name}: the gateway's heartbeat says operational (05h) after NMT start`);
    // CiA 852 §12.1: "all TPDOs shall be transmitted after the device transits into NMT
    // Operational state".
    const ids = this.host.tpdos.map((t) => t.cobId);
    await until(() => ids.every((id) => this.up.since(from, (f) => f.id === id).length), 5000);
    const missing = this.host.tpdos.filter((t) => !this.up.since(from, (f) => f.id === t.cobId).length).map((t) => t.n);
    check(missing.length === 0, `${c.name}: all ${n} TPDOs sent once on entering operational (CiA 852 §12.1)${missing.length ? '; missing TPDO ' + missing.join(', ') : ''}`);
    // The devices held at neutral until the gateway has seen every one of them there (neutral
    // interlock, docs/design/fault-policy.md): their PDOs run at 100 ms at most (oegw check's bus
    // load).
    await sleep(1000);
    const neutral = valueSet(c, null);
    for (const k of [0, 1, null]) {
      const set = valueSet(c, k);
      await this.sim.commands(set.lines);
      let left = await this.converge(set.expect, c.name === 'full' ? 30000 : 15000);
      let note = '';
      if (left.length && k !== null) {
        // A guest stalled past the wait above lets a device move before the gateway saw it at
        // neutral: the gateway holds it there (rightly). Once more from neutral, said in the line.
        info(`not yet as expected: ${left.slice(0, 4).join('; ')}; every device to neutral and the set again`);
        await this.sim.commands(neutral.lines);
        await sleep(1000);
        await this.sim.commands(set.lines);
        left = await this.converge(set.expect, c.name === 'full' ? 30000 : 15000);
        note = ' (second attempt, from neutral)';
      }
      const objects = this.host.tpdos.reduce((s, t) => s + t.entries.length, 0);
      check(left.length === 0, `${c.name}: ${k === null ? 'all back at neutral' : `value set ${k + 1}`}${note} (${set.lines.length} oegw-sim commands) decoded by node-canopen from ${n} TPDOs through the EDS mapping, ${objects} objects as expected${left.length ? ': ' + left.slice(0, 8).join('; ') + (left.length > 8 ? ` (+${left.length - 8})` : '') : ''}`);
    }
    // Every TPDO frame had the length its EDS mapping gives.
    const wrong = [];
    for (const t of this.host.tpdos) {
      const frames = this.up.since(from, (f) => f.id === t.cobId);
      const bad = frames.filter((f) => f.data.length !== t.bytes);
      if (bad.length) wrong.push(`TPDO ${t.n}: ${bad.length} of ${frames.length} frames not ${t.bytes} bytes`);
    }
    check(wrong.length === 0, `${c.name}: every TPDO frame as long as its mapping (${this.up.since(from, (f) => ids.includes(f.id)).length} frames) ${wrong.join(', ')}`);
  }
}

// ---------------------------------------------------------------------------------------------
// The demo cab's parts beyond the TPDOs.

// The end of a sub-device's fault as the gateway reports it (gateway/oe_device.cpp
// clear_subdevice_fault): EMCY 0000h naming the node, whether other errors remain or not (the
// last one with error register 00h, CiA 301 §7.2.7.2).
const recovered = (node) => (e) => e.code === 0x0000 && e.info[0] === node;
const codeText = (c) => (c === null ? 'success' : typeof c === 'number' ? hex(c) : c);

// Network indication (docs/guides/remote-sdo.md; canopen/301/sdo_remote.hpp):
// E0 00 00 00 <network> <node> 00 00 on a channel's request COB-ID, echoed on its response one.
// node-canopen has no command for it: raw frames.
async function indicate(up, tx, rx, net, node) {
  const from = up.mark();
  up.send(tx, Buffer.from([0xe0, 0, 0, 0, net, node, 0, 0]));
  const answer = await up.wait((f) => f.id === rx, SDO_MS, from);
  if (!answer) return 'no answer';
  if (answer.data[0] === 0xe0 && answer.data[4] === net && answer.data[5] === node) return null;
  if (answer.data[0] === 0x80) return answer.data.readUInt32LE(4);
  return `answer ${frameText(answer)}`;
}

// On the default channel (620h/5A0h): the code an indication got (null: echoed), and one that must
// be echoed.
const indicateDefault = (run, net, node) => indicate(run.up, 0x600 + GW, 0x580 + GW, net, node);
async function switchTarget(run, net, node, what) {
  const code = await indicateDefault(run, net, node);
  check(code === null, `network indication naming ${what} (network ${net}, node ${hex(node, 2)}) echoed: ${codeText(code)}`);
}

async function partSdo(run) {
  const h = run.host;
  // 1008h as the EDS gives it.
  await uploadStringEachWay(h, 'default channel', 0x1008, String(run.gwEds.getEntry(0x1008).value));
  const vendor = await h.u32(0x1018, 1, { blockTransfer: true });
  check(vendor === run.gwEds.getSubEntry(0x1018, 1).value >>> 0, `default channel: block upload of 1018h:01 (4 bytes) = ${hex(vendor)}`);
  await downloadEachWay(h, 'default channel', 0x1017, [150, 175, 200]);
  const back = async () => (await h.upload(0x1017, 0)).readUInt16LE(0);
  // An output: indicators.2 (left_grip's LEDs, 6200h:09h) by an expedited download; node_peer.sh
  // finds 203#05 on vcan1.
  await h.download(0x6200, 0x09, Buffer.from([0x05]));
  check((await h.upload(0x6200, 0x09)).readUInt8(0) === 0x05, 'default channel: 6200h:09h (indicators.2) = 05h, read back');

  // The gateway's own dictionary refuses, each with its documented code
  // (docs/guides/commission.md#commissioning-oegw-ctl: read-only 0601 0002h, a wrong length 0607
  // 0012h/0013h; CiA 852 decisions: an unconfigured indicator 0800 0020h; CiA 301 §7.2.4.3.17 for a
  // missing object/sub-index).
  const cases = [
    ['write of 1000h (const)', () => h.download(0x1000, 0, u32b(0)), 0x06010002],
    ['segmented write of 1008h (const, 24 bytes)', () => h.download(0x1008, 0, Buffer.from('not the name, not at all')), 0x06010002],
    ['1017h written with 4 bytes', () => h.download(0x1017, 0, u32b(200)), 0x06070012],
    ['1017h written with 1 byte', () => h.download(0x1017, 0, Buffer.from([200])), 0x06070013],
    ['upload of 2FFFh (no such object)', () => h.upload(0x2fff, 0), 0x06020000],
    ['upload of 1018h:07 (no such sub-index)', () => h.upload(0x1018, 7), 0x06090011],
    ['6200h:19h (indicators.4, not configured)', () => h.download(0x6200, 0x19, Buffer.from([1])), 0x08000020],
    ['3000h naming node 44h (no sub-device)', () => h.download(0x3000, 0, u32b(0x0144)), 0x06090011],
    ['3000h with code 02h (unknown)', () => h.download(0x3000, 0, u32b(0x027f)), 0x06090030],
  ];
  for (const [what, transfer, want] of cases) {
    const code = await h.abortOf(transfer());
    check(code === want, `default channel: ${what} aborted with ${hex(want)} (got ${codeText(code)})`);
  }
  check((await back()) === 200, '1017h unchanged by the refused writes (200)');
}

async function partBound(run) {
  const h = run.host;
  const o = { cobIdRx: BOUND.rx };
  const vendor = await h.u32(0x1018, 1, o);
  check(vendor === 0x58, `bound channel 690h/6B0h (node-canopen's second SDO client parameter): left_grip 1018h:01 expedited = ${hex(vendor)} (MCB-402 58h)`);
  await uploadStringEachWay(h, 'bound channel, left_grip', 0x2000, 'Frenzel + Berg', o);
  // 100Ch guard time (CiA 301, rw): nothing the gateway configures or relies on.
  await downloadEachWay(h, 'bound channel, left_grip', 0x100c, [100, 150, 200], o);
  await h.download(0x100c, 0, u16(0), o);
  let code = await h.abortOf(h.download(0x1800, 1, u32b(0x183), o));
  check(code === 0x08000021, `bound channel: write of left_grip's 1800h:01 refused with 08000021h (got ${codeText(code)})`);
  code = await h.abortOf(h.download(0x2180, 0, u16(50), o));
  check(code === 0x08000021, `bound channel: write of 2180h, which the MCB-402 driver writes at boot, refused with 08000021h (got ${codeText(code)})`);
  code = await h.abortOf(h.upload(0x2fff, 0, o));
  check(code === 0x06020000, `bound channel: left_grip's own abort for 2FFFh passed on unchanged, 06020000h (got ${codeText(code)})`);
  code = await indicate(run.up, BOUND.tx, BOUND.rx, DOWN_NET, 0x11);
  check(code === 0x08000021, `bound channel: a network indication refused with 08000021h (got ${codeText(code)})`);
}

async function partIndication(run) {
  const h = run.host;
  await switchTarget(run, DOWN_NET, 0x11, 'right_grip');
  const vendor = await h.u32(0x1018, 1);
  check(vendor === 0xb4, `through the indication: right_grip 1018h:01 expedited = ${hex(vendor)} (elobau B4h)`);
  // elobau 5001h (its default 20 last).
  await downloadEachWay(h, 'through the indication, right_grip', 0x5001, [30, 25, 20]);
  let code = await h.abortOf(h.download(0x1800, 1, u32b(0x191)));
  check(code === 0x08000021, `through the indication: write of right_grip's 1800h:01 refused with 08000021h (got ${codeText(code)})`);
  await switchTarget(run, DOWN_NET, 0x7f, 'seat_knob');
  await uploadStringEachWay(h, 'through the indication, seat_knob', 0x1008, 'MC1-2832-A7F-614-511');
  code = await indicateDefault(run, 9, 0x11);
  check(code === 0x06020000, `network indication naming network 9 refused with 06020000h (got ${codeText(code)})`);
  code = await indicateDefault(run, DOWN_NET, 0x44);
  check(code === 0x06090011, `network indication naming node 44h (no sub-device) refused with 06090011h (got ${codeText(code)})`);
  await switchTarget(run, UP_NET, GW, 'the gateway itself');
  const product = await h.u32(0x1018, 2);
  check(product === 0x852, `after it, 1018h:02 is the gateway's own again: ${hex(product)}`);
}

// seat_knob silent (its cable pulled): the remote codes of a sub-device that does not answer, then
// of one the gateway holds missing or is booting again; EMCY 7000h naming it and its clearing.
async function partRemoteFaults(run) {
  const h = run.host;
  const up = run.up;
  const tx = 0x600 + GW;
  const rx = 0x580 + GW;
  await switchTarget(run, DOWN_NET, 0x7f, 'seat_knob');
  const since = Date.now();
  await run.sim.commands(['seat_knob silent on']);
  let code = await h.abortOf(h.upload(0x1018, 1));
  check(code === 0x05040000, `a silent seat_knob: the remote upload aborted with 05040000h after the gateway's 500 ms (got ${codeText(code)})`);
  // Two requests back to back on the channel (raw frames: node-canopen queues its own): the
  // second while the first is in flight to the silent knob.
  const from = up.mark();
  up.send(tx, Buffer.from([0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]));
  up.send(tx, Buffer.from([0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]));
  const busy = await up.wait((f) => f.id === rx && f.data[0] === 0x80 && f.data.readUInt32LE(4) === 0x060a0023, SDO_MS, from);
  check(busy !== null, `a second request while one is in flight: aborted with 060A0023h (${frameText(busy)})`);
  await up.wait((f) => f.id === rx && f.t > (busy ? busy.t : 0), SDO_MS, from);  // the first one's end
  const lost = await h.waitEmcy((e) => e.code === 0x7000 && e.info[0] === 0x7f, 10000, since);
  check(lost !== null && lost.info.subarray(1, 5).toString('latin1') === 'seat',
    `EMCY 7000h naming seat_knob (node 7Fh, "seat": its position stale after 1 s, then its heartbeat lost after 3 s): ${lost ? lost.info.toString('hex') : 'none'}`);
  // While it is missing the gateway retries its boot (1 s, doubling): between retries a transfer
  // is refused as missing (0606 0000h), during one as being booted (0800 0022h).
  const seen = new Set();
  await until(async () => {
    seen.add(await h.abortOf(h.upload(0x1018, 1)));
    return seen.has(0x06060000) && seen.has(0x08000022);
  }, 15000, 100);
  check(seen.has(0x06060000), `seat_knob missing: remote upload aborted with 06060000h (seen ${[...seen].map(codeText).join(', ')})`);
  check(seen.has(0x08000022), `seat_knob being booted again: remote upload aborted with 08000022h (seen ${[...seen].map(codeText).join(', ')})`);
  // 3000h is the gateway's own: the host names the gateway again first.
  await switchTarget(run, UP_NET, GW, 'the gateway again');
  code = await h.abortOf(h.download(0x3000, 0, u32b(0x017f)));
  check(code === 0x08000022, `3000h position_error_reset for seat_knob while it is not operational: 08000022h (got ${codeText(code)})`);
  const quiet = Date.now();
  await run.sim.commands(['seat_knob silent off']);
  const back = await h.waitEmcy(recovered(0x7f), 45000, quiet);
  check(back !== null, `seat_knob back: EMCY 0000h (${back ? back.info.toString('hex') : '-'}) after ${back ? ((back.t - quiet) / 1000).toFixed(1) : '-'} s`);
  code = await h.abortOf(h.download(0x3000, 0, u32b(0x017f)));
  check(code === null, `3000h position_error_reset for seat_knob once operational again: carried out (got ${codeText(code)})`);
}

async function partEmcy(run) {
  const h = run.host;
  const since = Date.now();
  await run.sim.commands(['left_grip cable_break 1 on']);
  const e = await h.waitEmcy((x) => x.code === 0x3120, 10000, since);
  check(e !== null && e.info[0] === 0x03 && e.info[1] === 0x81, `left_grip's EMCY 3120h forwarded, read by node-canopen's EMCY consumer: node ${e ? hex(e.info[0], 2) : '-'}, its register ${e ? hex(e.info[1], 2) : '-'}`);
  const off = Date.now();
  await run.sim.commands(['left_grip cable_break 1 off']);
  const r = await h.waitEmcy((x) => x.code === 0x0000 && x.info[0] === 0x03, 10000, off);
  check(r !== null, `left_grip's error reset 0000h forwarded: ${r ? r.info.toString('hex') : 'none'}`);
}

async function partHeartbeat(run) {
  const h = run.host;
  const up = run.up;
  // The gateway as consumer of node-canopen's heartbeat (its 1016h:01 = 7Dh, 500 ms; CiA 852
  // Annex A): lost -> EMCY 8130h (1001h bit 4, communication), back -> that error cleared.
  h.device.eds.setHeartbeatProducerTime(100);
  await h.download(0x1016, 1, u32b((PEER << 16) | 500));
  await sleep(1000);
  let since = Date.now();
  h.device.eds.setHeartbeatProducerTime(0);
  const e = await h.waitEmcy((x) => x.code === 0x8130, 10000, since);
  check(e !== null && (e.register & 0x10) !== 0, `node-canopen's heartbeat stopped: the gateway's EMCY 8130h (host heartbeat lost), register ${e ? hex(e.register, 2) : '-'}, after ${e ? ((e.t - since) / 1000).toFixed(1) : '-'} s`);
  // CiA 301 1029h:01 = 0 (its default): the communication error takes the gateway from
  // operational to pre-operational. Waited for here, before the NMT start below: node-canopen
  // reports a consumed heartbeat only when its state changes, so a start sent before the
  // gateway's next heartbeat (its period is longer than this part's own steps) would leave no
  // change to see.
  check(await h.waitHeartbeat(0x7F, 5000, since), 'the communication error took the gateway to pre-operational (1029h:01 = 0)');
  since = Date.now();
  const from = up.mark();
  h.device.eds.setHeartbeatProducerTime(100);
  const r = await h.waitEmcy((x) => (x.register & 0x10) === 0, 10000, since);
  const sent = up.log.slice(from).filter((f) => f.own && f.id === 0x700 + PEER).length;
  check(r !== null && sent > 0, `its heartbeat back (${sent} sent): the communication error cleared, EMCY ${r ? hex(r.code, 4) : '-'} register ${r ? hex(r.register, 2) : '-'}`);
  await h.download(0x1016, 1, u32b(0));
  h.device.eds.setHeartbeatProducerTime(0);
  since = Date.now();
  h.device.nmt.startNode(GW);
  check(await h.waitHeartbeat(0x05, 5000, since), 'NMT start: the gateway operational again');

  // node-canopen as heartbeat consumer of the gateway (1016h: 3 x its 1017h).
  since = Date.now();
  run.gateway.signal('SIGSTOP');
  const lost = await until(() => h.timeouts.find((x) => x.t >= since && x.deviceId === GW), 10000);
  run.gateway.signal('SIGCONT');
  check(lost !== null, `node-canopen's heartbeat consumer (${h.consumerMs} ms) reports the gateway lost while it is stopped (SIGSTOP), after ${lost ? ((lost.t - since) / 1000).toFixed(1) : '-'} s`);
  since = Date.now();
  check((await h.waitHeartbeat(0x05, 10000, since)) !== null, 'and its heartbeat back (05h) after SIGCONT');
  // A gateway stopped longer than its sub-devices' consumer time has lost them when it reads their
  // late heartbeats (docs/design/fault-policy.md); they come back, every error with them.
  await sleep(2000);
  check((await until(() => h.lastRegister() === 0, 20000)) !== null, `every error of the gateway cleared again (its last EMCY's register ${hex(h.lastRegister(), 2)})`);
}

// The gateway as SYNC consumer (1005h 80h), node-canopen producing SYNC (1005h bit 30, 1006h
// 100 ms): TPDO 1 with transmission type 1 goes out once after every SYNC and never without one
// (CiA 301 §7.2.2.2: a synchronous cyclic TPDO is transmitted after every n-th SYNC).
async function partSync(run) {
  const h = run.host;
  const up = run.up;
  const tpdo1 = h.tpdos.find((t) => t.n === 1);
  let code = await h.abortOf(h.download(0x1800, 2, Buffer.from([1])));
  check(code === null, `TPDO 1 transmission type 1 (every SYNC) (${codeText(code)})`);
  const eds = h.device.eds;
  eds.setSyncCobId(0x80);
  eds.setSyncCyclePeriod(100000);  // µs
  const from = up.mark();
  eds.setSyncGenerationEnable(true);
  await sleep(2000);
  eds.setSyncGenerationEnable(false);
  await sleep(1500);  // the last SYNC's TPDO, from a gateway the guest may have stalled
  // As many TPDO 1 as SYNCs node-canopen sent (its own frames, logged as sent), none before the
  // first (values unchanged meanwhile: type FFh would send none). Counted, not paired: a stalled
  // guest may let two SYNCs reach the gateway before it answers the first.
  const frames = up.log.slice(from).filter((f) => (f.own && f.id === 0x80) || (!f.own && f.id === tpdo1.cobId));
  const syncs = frames.filter((f) => f.own).length;
  const tpdos = frames.filter((f) => !f.own).length;
  const first = frames.findIndex((f) => f.own);
  check(syncs >= 10 && tpdos === syncs && frames.slice(0, first).length === 0,
    `${syncs} SYNCs (080h, no counter) in 2 s, ${tpdos} TPDO 1 after them`);
  const quiet = up.mark();
  await run.sim.commands(['right_grip y 30']);
  await sleep(1000);
  check(up.since(quiet, (f) => f.id === tpdo1.cobId).length === 0, 'no SYNC: no TPDO 1 while right_grip moves (1 s)');
  code = await h.abortOf(h.download(0x1800, 2, Buffer.from([0xff])));
  await run.sim.commands(['right_grip y 0']);
  check(code === null, `TPDO 1 back to transmission type FFh (${codeText(code)})`);
}

// NMT states and what the TPDOs do in each (CiA 301 §7.3.2.2: PDOs only in operational, SDO not in
// stopped; CiA 852 §12.1: every TPDO on entering operational; reset communication restores the
// communication parameters 1000h..1FFFh, reset node the application's too).
async function partNmt(run) {
  const h = run.host;
  const up = run.up;
  const tpdo1 = h.tpdos.find((t) => t.n === 1);
  const quietWindow = async (from, ms) => { await sleep(ms); return up.since(from, (f) => h.tpdos.some((t) => t.cobId === f.id)).length; };
  const grip = async (x) => run.sim.commands([`right_grip x ${x}`]);

  // The stick to neutral first: after any fault the gateway holds an axis at neutral until it has
  // seen it there (docs/design/fault-policy.md); the grip's PDOs come every 100 ms.
  let since = Date.now();
  let from = up.mark();
  let f = null;
  for (let attempt = 0; attempt < 3 && !f; attempt++) {
    await grip(0);
    await sleep(500);
    from = up.mark();
    await grip(70);
    f = await up.wait((x) => x.id === tpdo1.cobId && x.data.readInt16LE(0) === conv.percent(2)(70), 3000, from);
  }
  check(f !== null, `operational: right_grip x 70 % -> TPDO 1 with x ${conv.percent(2)(70)} (${frameText(f)})`);
  // An NMT command, the heartbeat state it brings, and no TPDO while the grip moves to x.
  const quietState = async (command, state, name, x) => {
    const at = Date.now();
    command();
    check(await h.waitHeartbeat(state, 5000, at), `NMT ${name}: heartbeat ${hex(state, 2)}`);
    const start = up.mark();
    await grip(x);
    check((await quietWindow(start, 1500)) === 0, `${name}: no TPDO while right_grip moves to ${x} % (1.5 s)`);
  };

  await quietState(() => h.device.nmt.stopNode(GW), 0x04, 'stopped', -70);
  from = up.mark();
  const code = await h.abortOf(h.upload(0x1000, 0, { timeout: 1000 }));
  check(code === 0x05040000 && up.since(from, (x) => x.id === 0x580 + GW).length === 0,
    `stopped: an SDO upload gets no answer (node-canopen's own time-out, ${codeText(code)})`);

  await quietState(() => h.device.nmt.enterPreOperational(GW), 0x7f, 'pre-operational', -40);
  check((await h.u32(0x1000, 0)) === run.gwEds.getEntry(0x1000).value >>> 0, 'pre-operational: SDO answered (1000h)');

  since = Date.now();
  from = up.mark();
  h.device.nmt.startNode(GW);
  check(await h.waitHeartbeat(0x05, 5000, since), 'NMT start: heartbeat 05h');
  await until(() => h.tpdos.every((t) => up.since(from, (x) => x.id === t.cobId).length), 5000);
  const sent = h.tpdos.filter((t) => up.since(from, (x) => x.id === t.cobId).length).length;
  check(sent === h.tpdos.length, `operational again: ${sent} of ${h.tpdos.length} TPDOs sent on the transition (CiA 852 §12.1)`);
  await until(() => h.value(0x6401, 1) === conv.percent(2)(-40), 3000);
  check(h.value(0x6401, 1) === conv.percent(2)(-40), `operational again: joystick 1 x = ${h.value(0x6401, 1)} (right_grip at -40 %)`);

  since = Date.now();
  from = up.mark();
  h.device.nmt.resetCommunication(GW);
  const boot = await up.wait(frameIs(0x700 + GW, [0x00]), 5000, from);
  check(boot !== null, 'NMT reset communication: boot-up 720h#00');
  check(await h.waitHeartbeat(0x7f, 5000, since), 'then heartbeat 7Fh (pre-operational)');
  const c1 = await h.u32(0x1800, 1);
  const c5 = await h.u32(0x1804, 1);
  check(c1 === 0x800001a0 && c5 === 0x80000000, `reset communication: TPDO COB-IDs back at their power-on values, 1800h:01 ${hex(c1)}, 1804h:01 ${hex(c5)}`);
  const enable = (await h.upload(0x6423, 0)).readUInt8(0);
  check(enable === 1, `reset communication keeps the application's 6423h (${enable})`);
  from = up.mark();
  h.device.nmt.startNode(GW);
  check((await quietWindow(from, 1500)) === 0, 'started after reset communication: no frame on the TPDO COB-IDs the host had set (all invalid again)');

  since = Date.now();
  from = up.mark();
  h.device.nmt.resetNode(GW);
  check((await up.wait(frameIs(0x700 + GW, [0x00]), 5000, from)) !== null, 'NMT reset node: boot-up 720h#00');
  check(await h.waitHeartbeat(0x7f, 5000, since), 'then heartbeat 7Fh');
  const e2 = (await h.upload(0x6423, 0)).readUInt8(0);
  const hb = (await h.upload(0x1017, 0)).readUInt16LE(0);
  check(e2 === 0 && hb === 200, `reset node: 6423h back to FALSE (${e2}), 1017h the mapping file's 200 ms (${hb})`);
  await grip(0);
}

// LSS on the downstream bus (CiA 305), node-canopen as LSS master on vcan1: take the button
// cluster's node-ID away, find it by fastscan, give it 40h and read it there, then give 31h back.
async function partLss(run, downHost) {
  const h = run.host;
  const down = run.down;
  const lss = downHost.lss;
  const code = await indicateDefault(run, DOWN_NET, 0x31);
  const address = [];
  for (let s = 1; s <= 4; s++) address.push(await h.u32(0x1018, s));
  await indicateDefault(run, UP_NET, GW);
  check(code === null, `cluster's LSS address read through the gateway (1018h:01..04): ${address.map((a) => hex(a)).join(' ')}`);
  const [vendorId, productCode, revisionNumber, serialNumber] = address;
  await lss.switchModeSelective({ vendorId, productCode, revisionNumber, serialNumber, timeout: 3000 });
  await lss.configureNodeId(0xff, 3000);
  lss.switchModeGlobal(0);
  const since = Date.now();
  downHost.nmt.resetCommunication(0x31);
  const lost = await h.waitEmcy((e) => e.code === 0x7000 && e.info[0] === 0x31, 10000, since);
  check(lost !== null, 'cluster without node-ID (LSS configure node-ID FFh, NMT reset communication): EMCY 7000h naming 31h upstream');
  // A fastscan step waits `timeout` for no answer (a bit that is 1): 1 s, so that a stalled guest
  // does not turn a late answer into a wrong bit; ten such bits in the cluster's address.
  const found = await lss.fastscan({ timeout: 1000 });
  check(found !== null && found.vendorId === vendorId && found.productCode === productCode && found.revisionNumber === revisionNumber && found.serialNumber === serialNumber,
    `LSS fastscan finds it: ${found ? [found.vendorId, found.productCode, found.revisionNumber, found.serialNumber].map((a) => hex(a)).join(' ') : 'nothing'}`);
  let from = down.mark();
  await lss.configureNodeId(0x40, 3000);
  lss.switchModeGlobal(0);
  const boot40 = await down.wait(frameIs(0x740, [0x00]), 5000, from);
  check(boot40 !== null, 'configure node-ID 40h, switch to waiting: boot-up 740h#00 on vcan1');
  downHost.eds.addSdoClientParameter(0x40, 0x640, 0x5c0);
  const product = await downHost.sdo.upload({ deviceId: 0x40, index: 0x1018, subIndex: 2, timeout: SDO_MS });
  check(product.readUInt32LE(0) === productCode, `node-canopen's SDO client reads it at 40h: 1018h:02 = ${hex(product.readUInt32LE(0))}`);
  await lss.switchModeSelective({ vendorId, productCode, revisionNumber, serialNumber, timeout: 3000 });
  await lss.configureNodeId(0x31, 3000);
  lss.switchModeGlobal(0);
  const back = Date.now();
  from = down.mark();
  downHost.nmt.resetCommunication(0x40);
  const boot31 = await down.wait(frameIs(0x731, [0x00]), 5000, from);
  check(boot31 !== null, 'node-ID 31h configured again, NMT reset communication: boot-up 731h#00');
  const clear = await h.waitEmcy(recovered(0x31), 45000, back);
  check(clear !== null, `the gateway boots it again: EMCY 0000h (${clear ? clear.info.toString('hex') : '-'}) after ${clear ? ((clear.t - back) / 1000).toFixed(1) : '-'} s`);
  downHost.eds.removeSdoClientParameter(0x40);
}

// ---------------------------------------------------------------------------------------------

async function main() {
  const parts = partArgs.length ? partArgs : ['demo', 'joystick2', 'pedal2', 'full'];
  const wants = (c, p) => parts.includes(c) || parts.includes(`${c}:${p}`);
  const up = new Bus('vcan0');
  // Downstream only what the checks read — NMT, LSS answers (7E4h), the LSS part's node at 40h
  // (boot-up 740h, SDO answers 5C0h) and back at 31h (731h) — so that the full set's ~1,700
  // frames/s (1,200 SDO answers in its boot alone) stay in the kernel: a loaded guest does not
  // schedule this process often enough to drain its socket of them.
  const down = new Bus('vcan1', [0x000, 0x7e4, 0x740, 0x5c0, 0x731].map((id) => ({ id, mask: 0x7ff })));
  const downHost = new Device({ id: PEER_DOWN });
  down.attach(downHost);
  downHost.start();
  info(`node-canopen ${req('canopen/package.json').version}, socketcan ${req('socketcan/package.json').version} on node ${process.version}`);

  for (const name of ['demo', 'joystick2', 'pedal2', 'full']) {
    if (!parts.some((p) => p === name || p.startsWith(`${name}:`))) continue;
    console.log(`== ${name} cab (${elapsed()} s)`);
    const run = new Run(cabs[name], up, down);
    try {
      await run.start();
      await run.identity();
      if (name !== 'demo' || wants(name, 'tpdo')) await run.tpdoCheck();
      else {
        await run.enableTpdos();
        run.host.device.nmt.startNode(GW);
      }
      if (name === 'demo') {
        for (const [p, fn] of [['sdo', partSdo], ['bound', partBound], ['indication', partIndication],
          ['remote_faults', partRemoteFaults], ['emcy', partEmcy], ['heartbeat', partHeartbeat], ['sync', partSync], ['nmt', partNmt],
          ['lss', (r) => partLss(r, downHost)]]) {
          if (!wants(name, p)) continue;
          console.log(`-- demo: ${p} (${elapsed()} s)`);
          try {
            await fn(run);
          } catch (e) {
            check(false, `demo ${p}: ${e.stack || e}`);
          }
        }
      }
    } catch (e) {
      check(false, `${name}: ${e.stack || e}`);
    }
    try {
      await run.stop();
    } catch (e) {
      check(false, `${name}: stopping: ${e}`);
    }
    console.log(`== ${name} cab done (${elapsed()} s)`);
  }
  down.detach(downHost);
  console.log(`node-canopen host: ${passes} passed, ${fails} failed, ${elapsed()} s`);
  process.exit(Math.min(fails, 100));
}

main().catch((e) => {
  console.log(`FAIL ${e.stack || e}`);
  process.exit(Math.min(fails + 1, 100));
});
