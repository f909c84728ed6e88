// The harness's result: one JSON object of the run's figures. `cargo xtask emulate` reads
// it and adds the firmware's own figures, decoded from the defmt log the harness wrote.

import { NOMINAL_CLK_HZ } from './chip.mjs';

/// `x` to `n` decimal places.
export function round(x, n) {
  const f = 10 ** n;
  return Math.round(x * f) / f;
}

/// Share of `seconds` of the nominal clock that `cycles` took, in percent.
const loadPct = (cycles, seconds) => round((100 * cycles) / (seconds * NOMINAL_CLK_HZ), 2);

/// The result from the run's parts, in the key order `cargo xtask emulate` and the
/// baseline outputs were written with.
/// `run` holds the figures of every boot summed (instructions and cycles of both cores);
/// `chip` and `devices` are the last boot's; `resets` lists the watchdog resets.
export function buildResult({ args, chip, run, meter, matchMeter, rtt, telemetryBytes, usb, world, motors, truth, devices, faults, resets, stacks, profile }) {
  const { rp, core, core1, clock, messages } = chip;
  const simS = clock.nanos / 1e9;
  const { flow, imu, imuBus, depth, depthBus, camera } = devices;
  return {
    sim_seconds: round(simS, 3),
    wall_seconds: round(run.wallS, 3),
    sim_per_wall: round(simS / run.wallS, 2),
    stop_reason: run.stopReason,
    instructions: run.instructions,
    cycles: run.cycles,
    cpu_load_pct: loadPct(run.cycles, simS),
    clk_sys_hz: rp.clkSys,
    ...meter.summary(),
    ...matchMeter.summary(),
    defmt_bytes: rtt.bytes.length,
    telemetry_bytes: telemetryBytes,
    world: args.noWorld ? 'still (no host-sim)' : 'host-sim serve',
    world_requests: world.requests,
    max_wheel_duty: round(motors.maxAbs, 3),
    truth,
    devices: {
      flow: { reads: flow.bursts, register_reads: flow.regReads, writes: flow.writes, resets: flow.resets, spi_mode_errors: flow.modeErrors },
      imu: { samples: imu.samples, resets: imu.resets, nacks: imuBus.nacks },
      depth: { transactions: depthBus.transactions, nacks: depthBus.nacks, ...depth.stats() },
      camera: camera.stats,
      uart0_rx_bytes: camera.uartRxBytes,
      uart_tx_overflows: [rp.uart[0].txOverflows || 0, rp.uart[1].txOverflows || 0],
      core1: core1.launched
        ? { launched: true, instructions: run.core1Instructions, cycles: run.core1Cycles, load_pct: loadPct(run.core1Cycles, simS), fifo_words: core1.fifoWords }
        : { launched: false, launch_words: core1.launchWords },
    },
    usb,
    faults_injected: faults.report(),
    resets,
    stacks,
    emulator_messages: [...messages].slice(0, 20).map(([k, n]) => `${n}x ${k}`),
    ...profile,
  };
}
