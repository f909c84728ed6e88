// The harness's command line.

import path from 'node:path';
import { parseFault } from './faults.mjs';

export const USAGE = `usage: node harness.mjs --elf FW.elf [--bin FW.bin] [--scenario FILE] [--seconds N]
         [--seed N] [--host-sim BIN | --no-world] [--telemetry FILE] [--defmt FILE]
         [--usb-telemetry FILE | --no-usb] [--truth FILE] [--fault NAME@T+S[/D]]...
         [--max-wall S] [--json] [--quiet]
       node harness.mjs --self-test | --help`;

/// Parses `argv` (without node and the script). `repo` is the workspace root, for the
/// default scenario. Throws on anything it does not know.
export function parseArgs(argv, repo) {
  const a = {
    bin: null,
    elf: null,
    scenario: path.join(repo, 'host-sim/scenarios/seed-mat.toml'),
    seconds: 10,
    seed: 1,
    hostSim: null,
    noWorld: false,
    telemetry: null,
    usbTelemetry: null,
    noUsb: false,
    defmt: null,
    truth: null,
    faults: [],
    maxWall: 0,
    json: false,
    quiet: false,
    selfTest: false,
    help: false,
  };
  for (let i = 0; i < argv.length; i++) {
    const k = argv[i];
    const v = () => {
      if (i + 1 >= argv.length) throw new Error(`${k} needs a value`);
      return argv[++i];
    };
    switch (k) {
      case '--bin': a.bin = v(); break;
      case '--elf': a.elf = v(); break;
      case '--scenario': a.scenario = v(); break;
      case '--seconds': a.seconds = Number(v()); break;
      case '--seed': a.seed = Number(v()); break;
      case '--host-sim': a.hostSim = v(); break;
      case '--no-world': a.noWorld = true; break;
      case '--telemetry': a.telemetry = v(); break;
      case '--usb-telemetry': a.usbTelemetry = v(); break;
      case '--no-usb': a.noUsb = true; break;
      case '--defmt': a.defmt = v(); break;
      case '--truth': a.truth = v(); break;
      case '--fault': a.faults.push(parseFault(v())); break;
      case '--max-wall': a.maxWall = Number(v()); break;
      case '--json': a.json = true; break;
      case '--quiet': a.quiet = true; break;
      case '--self-test': a.selfTest = true; break;
      case '-h': case '--help': a.help = true; break;
      default: throw new Error(`unknown argument ${k}\n${USAGE}`);
    }
  }
  if (a.selfTest || a.help) return a;
  if (!a.elf) throw new Error('--elf is required (--bin is optional)');
  if (!(a.seconds > 0)) throw new Error('--seconds must be positive');
  if (a.noUsb && a.usbTelemetry) throw new Error('--usb-telemetry needs the USB host: drop --no-usb');
  // Without --defmt the log goes beside the telemetry.
  if (!a.defmt && a.telemetry) a.defmt = a.telemetry.replace(/(\.bin)?$/, '.defmt');
  return a;
}
