// Drive CNCjs (npm cncjs: its server, its Grbl controller and sender) through
// its own socket.io client API, as its web page does: open mlip-grbl's
// pseudo-terminal as a Grbl port, read the DRO, jog as its axes widget does,
// load a file, run it, hold and resume it, and print one JSON line per event.
//
//   node drive.js --cncjs-port N --tty PATH --file FILE --config FILE [--jog]
//                 [--hold-after LINES | --hold-at-line N] [--override-at-lines N,M]
//                 [--jog-cancel DIST,FEED,AFTER] [--shot PNG] [--deadline S]
//
// --hold-after: hold once its sender has LINES answered; --hold-at-line: once
// the status report's Ln is N lines past the first Ln of the run and the
// machine moves (a file whose lines are all answered before it moves).
// --override-at-lines N,M: its feed override buttons (-10 %: 0x92; then
// 100 %: 0x90) at Ln N and M past the first Ln of the run, as --hold-at-line
// counts. --jog-cancel DIST,FEED,AFTER: once the file is done, a jog
// ($J=G21 G91 X<DIST> F<FEED>) cancelled by its jogCancel (0x85) once the
// reports show it at FEED and AFTER mm along.
// Every event carries `wall` (the wall clock, s) besides `t`.
//
// Every wait is on a condition (a state, a position, lines answered, status
// reports counted) with a generous deadline (DEADLINE, --deadline), never a
// fixed sleep: the host is loaded, the emulated VM slower still.
'use strict';
const fs = require('fs');
const http = require('http');
const path = require('path');
const { spawn } = require('child_process');
const io = require('socket.io-client');

const arg = (k, d) => { const i = process.argv.indexOf(k); return i > 0 ? process.argv[i + 1] : d; };
const PORT = Number(arg('--cncjs-port'));
const TTY = arg('--tty');
const FILE = arg('--file');
const CONFIG = arg('--config');
const HOLD_AFTER = arg('--hold-after') ? Number(arg('--hold-after')) : null;
const HOLD_AT_LINE = arg('--hold-at-line') ? Number(arg('--hold-at-line')) : null;
const JOG = process.argv.includes('--jog');
const OVERRIDE_AT = arg('--override-at-lines') ? arg('--override-at-lines').split(',').map(Number) : null;
const JOG_CANCEL = arg('--jog-cancel') ? arg('--jog-cancel').split(',').map(Number) : null;
const DEADLINE = Number(arg('--deadline', 60)) * 1000; // ms, for any one condition
const SHOT = arg('--shot'); // a PNG of CNCjs's page (Debian's chromium, headless)
const T0 = Date.now();
const say = (o) => process.stdout.write(JSON.stringify({ ...o, t: (Date.now() - T0) / 1000,
  wall: Date.now() / 1000 }) + '\n');
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function post(p, body) {
  return new Promise((resolve, reject) => {
    const data = JSON.stringify(body);
    const req = http.request({ host: '127.0.0.1', port: PORT, path: p, method: 'POST',
      headers: { 'Content-Type': 'application/json', 'Content-Length': Buffer.byteLength(data) } },
    (res) => { let s = ''; res.on('data', (c) => { s += c; }); res.on('end', () => resolve(JSON.parse(s))); });
    req.on('error', reject);
    req.end(data);
  });
}

// CNCjs's own page in headless Chromium: its Connection widget opens the port
// (joining the controller this script opened) and its DRO shows where mlip
// stands.
async function screenshot(st) {
  const { chromium } = require('playwright-core');
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  try {
    const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
    const url = `http://127.0.0.1:${PORT}/`;
    await page.goto(url, { waitUntil: 'load', timeout: DEADLINE });
    // the Connection widget, as a person uses it: the port, then Open
    await page.click('text=Choose a port', { timeout: DEADLINE });
    await page.getByText(TTY, { exact: true }).first().click({ timeout: DEADLINE });
    await page.click('button:has-text("Open")', { timeout: DEADLINE });
    const x = st.mpos[0].toFixed(3);
    let shown = false;
    for (const end = Date.now() + DEADLINE; Date.now() < end && !shown;) {
      const text = await page.evaluate(() => document.body.innerText);
      shown = text.includes(x) && text.includes('Idle');
      if (!shown) await sleep(100);
    }
    await page.screenshot({ path: SHOT, fullPage: true });
    say({ event: 'screenshot', path: SHOT, dro_shows_x: shown, x });
  } finally {
    await browser.close();
  }
}

async function main() {
  // CNCjs lists the ports its configuration names beside the system's serial
  // ports ("ports" in ~/.cncrc): the way to offer it mlip-grbl's terminal
  fs.writeFileSync(CONFIG, JSON.stringify({ ports: [{ path: TTY, manufacturer: 'mlip-grbl' }] }));
  const bin = path.join(__dirname, 'node_modules', 'cncjs', 'bin', 'cncjs');
  const server = spawn(process.execPath, [bin, '-p', String(PORT), '-H', '127.0.0.1', '-c', CONFIG],
    { stdio: ['ignore', 'pipe', 'pipe'], env: { ...process.env, HOME: path.dirname(CONFIG) } });
  let log = '';
  server.stdout.on('data', (d) => { log += d; });
  server.stderr.on('data', (d) => { log += d; });
  const done = (code) => { server.kill('SIGTERM'); setTimeout(() => process.exit(code), 300); };
  let token = null;
  for (const end = Date.now() + DEADLINE; Date.now() < end && !token;) {
    try { token = (await post('/api/signin', { token: '' })).token; } catch (e) { await sleep(100); }
  }
  if (!token) { say({ event: 'error', msg: 'cncjs did not start', log }); return done(1); }
  say({ event: 'cncjs', version: require('./node_modules/cncjs/package.json').version });
  const socket = io.connect(`http://127.0.0.1:${PORT}`, { query: `token=${token}` });
  const st = { state: null, mpos: null, wpos: null, workflow: null, sender: null, lines: [],
    reports: 0, report: null };
  socket.on('controller:state', (type, state) => {
    const s = state.status || {};
    const a = s.activeState + (s.subState !== undefined && s.subState >= 0 && s.activeState === 'Hold' ? `:${s.subState}` : '');
    const mpos = s.mpos && ['x', 'y', 'z'].map((k) => Number(s.mpos[k]));
    if (a !== st.state) say({ event: 'state', state: a, mpos, ln: s.ln });
    st.state = a; st.mpos = mpos; st.wpos = s.wpos; st.ln = s.ln; st.feed = Number(s.feedrate);
    // Ov comes in the first report after a change (report.c), whoever asked
    // for it: CNCjs's own 4 Hz polls are parsed into its state, not echoed
    const ov = s.ov && s.ov.length ? Number(s.ov[0]) : null;
    if (ov !== null && ov !== st.ovFeed) { st.ovFeed = ov; st.ovWall = Date.now() / 1000; }
  });
  socket.on('workflow:state', (w) => { st.workflow = w; });
  socket.on('sender:status', (s) => { st.sender = s; });
  socket.on('serialport:read', (line) => {
    st.lines.push(line);
    if (line.startsWith('<')) { // a `?` of ours answered
      st.reports += 1; st.report = line; st.reportWall = Date.now() / 1000;
    }
    if (/^error|^\[MSG|^Grbl/.test(line)) say({ event: 'read', line });
  });
  const until = async (pred, ms, what) => {
    const end = Date.now() + ms;
    while (Date.now() < end) { if (pred()) return true; await sleep(20); }
    say({ event: 'timeout', what, state: st.state, mpos: st.mpos, workflow: st.workflow });
    return false;
  };
  const cmd = (...a) => socket.emit('command', TTY, ...a);
  socket.emit('open', TTY, { controllerType: 'Grbl', baudrate: 115200 }, (err) => {
    if (err) say({ event: 'error', msg: String(err) });
  });
  if (!await until(() => st.state === 'Idle', DEADLINE, 'connect')) return done(1);
  // CNCjs passes on what the port says only once its open callback has
  // joined this socket to the controller: the welcome mlip-grbl sends as the
  // terminal opens (Grbl's after the reset a USB port's DTR gives) can come
  // before. Then its reset button (ctrl-x) asks for it again, as a user does.
  const welcome = () => st.lines.some((l) => l.startsWith('Grbl '));
  if (!welcome()) {
    say({ event: 'welcome_before_join' });
    cmd('reset');
    if (!await until(welcome, DEADLINE, 'the welcome after a reset')) return done(1);
    if (!await until(() => st.state === 'Idle', DEADLINE, 'idle after the reset')) return done(1);
  }
  say({ event: 'connected', state: st.state, mpos: st.mpos });

  if (JOG) {
    // jog as the axes widget does: relative, rapid, then back to absolute
    cmd('gcode', 'G91');
    cmd('gcode', 'G0 X2 Y1');
    cmd('gcode', 'G90');
    if (!await until(() => st.state === 'Idle' && st.mpos && Math.abs(st.mpos[0] - 2) < 1e-3 &&
      Math.abs(st.mpos[1] - 1) < 1e-3, DEADLINE, 'jog')) return done(1);
    say({ event: 'jogged', mpos: st.mpos });
  }

  const text = fs.readFileSync(FILE, 'utf8');
  await new Promise((resolve) => cmd('gcode:load', path.basename(FILE), text, {}, () => resolve()));
  const tRun = Date.now();
  cmd('gcode:start');
  say({ event: 'run' });
  if (!await until(() => st.state === 'Run', DEADLINE, 'run')) return done(1);
  // Within one report: `?` written right behind the real-time byte, as its
  // console sends it, answered in order; a report CNCjs asked for itself
  // before the byte may come first (then one more `?`). The reports read.
  const reportsAfter = async (what, want) => {
    const seen = [];
    seen.walls = []; // when each came (not in its JSON)
    for (let k = 0; k < 2 && !(seen.length && want(seen[seen.length - 1])); k++) {
      const n = st.reports;
      socket.emit('write', TTY, '?');
      if (!await until(() => st.reports > n, DEADLINE, what)) return null;
      seen.push(st.report);
      seen.walls.push(st.reportWall);
    }
    return seen;
  };
  // its pause and resume buttons: `!`, then `~`
  const holdResume = async () => {
    const sent = Date.now() / 1000;
    cmd('gcode:pause');
    const seen = await reportsAfter('a report after the hold', (r) => r.startsWith('<Hold'));
    if (!seen) return false;
    say({ event: 'hold', sent, reports: seen });
    if (!await until(() => st.state === 'Hold:0', DEADLINE, 'hold')) return false;
    const before = st.mpos;
    const atRest = Date.now() / 1000;
    // held: where it stands in three more reports, asked for as its console's `?` does
    for (let k = 0; k < 3; k++) {
      const n = st.reports;
      socket.emit('write', TTY, '?');
      if (!await until(() => st.reports > n, DEADLINE, 'a report while held')) return false;
    }
    const m = /MPos:([-0-9.]+),([-0-9.]+),([-0-9.]+)/.exec(st.report);
    say({ event: 'held', before, after: m && m.slice(1).map(Number), report: st.report,
      state: st.state, at_rest: atRest });
    const resumed = Date.now() / 1000;
    cmd('gcode:resume');
    const again = await reportsAfter('a report after the resume', (r) => r.startsWith('<Run'));
    if (!again) return false;
    say({ event: 'resumed', sent: resumed, reports: again });
    return true;
  };
  // Ln n lines past the first Ln of the run, moving
  let ln0 = null;
  const atLine = (n) => () => {
    if (ln0 === null && st.state === 'Run' && st.ln !== undefined) ln0 = st.ln;
    return ln0 !== null && st.state === 'Run' && st.ln >= ln0 + n && st.feed > 0;
  };
  // its feed override button: the byte, then reports until one carries the
  // new Ov. ov_wall: when that report came; when CNCjs's own poll took it
  // (its reports are parsed, not echoed: Ov is in the first report after a
  // change only), when CNCjs's state showed it (at most its 250 ms emit
  // period after that report)
  const override = async (kind, value, pct) => {
    const sent = Date.now() / 1000;
    const has = (r) => r.includes(`|Ov:${pct},`);
    cmd('feedOverride', value);
    const seen = await reportsAfter(kind, (r) => has(r) || (st.ovFeed === pct && st.ovWall >= sent));
    if (!seen) return false;
    const k = seen.findIndex(has);
    if (k < 0 && !await until(() => st.ovFeed === pct && st.ovWall >= sent, DEADLINE,
      `${kind}: Ov in CNCjs's state`)) return false;
    say({ event: kind, sent, reports: seen, ov_wall: k >= 0 ? seen.walls[k] : st.ovWall,
      ov_in: k >= 0 ? 'our report' : "CNCjs's state" });
    return true;
  };
  if (HOLD_AFTER !== null) {
    if (!await until(() => st.sender && st.sender.received >= HOLD_AFTER && st.state === 'Run',
      DEADLINE, 'lines before the hold')) return done(1);
    if (!await holdResume()) return done(1);
  } else if (HOLD_AT_LINE !== null) {
    if (!await until(atLine(HOLD_AT_LINE), 600000, 'the line to hold at')) return done(1);
    if (!await holdResume()) return done(1);
  }
  if (OVERRIDE_AT !== null) {
    if (!await until(atLine(OVERRIDE_AT[0]), 600000, 'the line of the override')) return done(1);
    if (!await override('override-down', -10, 90)) return done(1);
    if (!await until(atLine(OVERRIDE_AT[1]), 600000, 'the line of the reset')) return done(1);
    if (!await override('override-reset', 0, 100)) return done(1);
  }
  const finished = () => st.state === 'Idle' && st.sender && st.sender.sent === st.sender.total &&
    st.sender.received === st.sender.total;
  if (!await until(finished, 600000, 'finish')) return done(1);
  say({ event: 'done', seconds: (Date.now() - tRun) / 1000, state: st.state, mpos: st.mpos,
    total: st.sender.total, errors: st.lines.filter((l) => /^error/.test(l)).length });
  if (JOG_CANCEL !== null) {
    const [dist, feed, after] = JOG_CANCEL;
    const x0 = st.mpos[0];
    cmd('gcode', `$J=G21 G91 X${dist} F${feed}`);
    if (!await until(() => st.state === 'Jog' && st.feed === feed && st.mpos[0] >= x0 + after,
      DEADLINE, 'the jog at its feed')) return done(1);
    const sent = Date.now() / 1000;
    cmd('jogCancel');
    // the first report after it (Grbl: Jog while it brakes, then Idle)
    const seen = await reportsAfter('a report after the jog cancel', () => true);
    if (!seen) return done(1);
    say({ event: 'jog-cancel', sent, reports: seen });
    if (!await until(() => st.state === 'Idle', DEADLINE, 'rest after the cancel')) return done(1);
    say({ event: 'jog-stopped', mpos: st.mpos, x0 });
  }
  if (SHOT) await screenshot(st);
  socket.emit('close', TTY);
  await sleep(300);
  return done(0);
}

main().catch((e) => { say({ event: 'error', msg: String(e && e.stack) }); process.exit(1); });
