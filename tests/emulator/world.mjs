// The world the firmware lives in: `host-sim serve` answering what each sensor sees at
// the simulated instant it is read, or a still world without host-sim.

import { spawn, execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

/// `host-sim serve` over two FIFOs, one JSON line per request and per reply. FIFOs
/// instead of pipes let the emulator loop block on each reply, so the world is read at
/// exactly the simulated instant the firmware asks.
export class HostWorld {
  constructor(bin, scenario, seed) {
    this.dir = fs.mkdtempSync(path.join(os.tmpdir(), 'bugbot-emu-'));
    this.toSim = path.join(this.dir, 'to-sim');
    this.fromSim = path.join(this.dir, 'from-sim');
    execFileSync('mkfifo', [this.toSim, this.fromSim]);
    // The shell opens both FIFOs before exec; opening our ends below unblocks it.
    this.child = spawn(
      'sh',
      ['-c', 'exec "$0" "$@" <"$TO_SIM" >"$FROM_SIM"', bin, 'serve', scenario, '--seed', String(seed)],
      { stdio: ['ignore', 'ignore', 'inherit'], env: { ...process.env, TO_SIM: this.toSim, FROM_SIM: this.fromSim } },
    );
    this.out = fs.openSync(this.toSim, 'w');
    this.in = fs.openSync(this.fromSim, 'r');
    this.pending = Buffer.alloc(0);
    this.requests = 0;
    this.t_s = 0;
  }

  /// Sends `obj` and waits for its reply; an `error` reply throws.
  request(obj) {
    fs.writeSync(this.out, JSON.stringify(obj) + '\n');
    this.requests++;
    const chunk = Buffer.alloc(65536);
    for (;;) {
      const nl = this.pending.indexOf(10);
      if (nl >= 0) {
        const line = this.pending.subarray(0, nl).toString();
        this.pending = this.pending.subarray(nl + 1);
        const reply = JSON.parse(line);
        if (reply.error) throw new Error(`host-sim: ${reply.error} (request ${JSON.stringify(obj)})`);
        return reply;
      }
      const n = fs.readSync(this.in, chunk, 0, chunk.length, null);
      if (n === 0) throw new Error('host-sim serve closed its output (is `serve` in host-sim\'s CLI?)');
      this.pending = Buffer.concat([this.pending, chunk.subarray(0, n)]);
    }
  }

  /// Moves the world on to `t_s` with the wheels at duties `left` and `right` (-1..1);
  /// nothing to ask if time has not moved.
  advance(t_s, left, right) {
    if (t_s <= this.t_s) return null;
    this.t_s = t_s;
    return this.request({ cmd: 'advance', t_s, left, right });
  }
  flow() { return this.request({ cmd: 'flow' }); }
  gyro() { return this.request({ cmd: 'gyro' }); }
  depth() { return this.request({ cmd: 'depth' }); }
  tags() { return this.request({ cmd: 'tags' }); }
  truth() { return this.request({ cmd: 'truth' }); }

  close() {
    try { fs.closeSync(this.out); } catch {}
    try { fs.closeSync(this.in); } catch {}
    try { this.child.kill(); } catch {}
    fs.rmSync(this.dir, { recursive: true, force: true });
  }
}

/// No world: the robot stands on a good surface in front of nothing. Lets the firmware
/// boot and tick without host-sim (plumbing tests).
export class StillWorld {
  constructor() { this.requests = 0; this.t_s = 0; this.n = 0; }
  advance(t_s) { this.t_s = Math.max(this.t_s, t_s); return null; }
  flow() { return { forward_counts: 0, right_counts: 0, squal: 120 }; }
  // Alternating +-1 count of noise: the firmware's bias calibration wants a little spread.
  gyro() { this.n++; return { rate_mdps: this.n & 1 ? 30 : -30 }; }
  depth() { return { ranges_mm: Array(8).fill(null) }; }
  tags() { return { tags: [] }; }
  truth() { return null; }
  close() {}
}

/// The world the command line asks for: still with `--no-world`, else `host-sim serve`
/// from `--host-sim` or the workspace's release build.
export function openWorld(args, repo) {
  if (args.noWorld) return new StillWorld();
  const bin = args.hostSim || path.join(repo, 'target/release/host-sim');
  if (!fs.existsSync(bin)) throw new Error(`no host-sim at ${bin}: build it or pass --no-world`);
  return new HostWorld(bin, args.scenario, args.seed);
}
