// Third-party Modbus TCP peer for the arm simulator: the npm `jsmodbus` client (4.x) reads the
// input registers (function 04), writes a HOME command block (function 16, registers 0..13, see
// rig_daemon/backends/arm_register_map.h), polls until the arm holds at home, stops it with a
// single-register write (function 06) and prints one JSON document with what it read.
// Usage: node modbus_arm_jsmodbus.cjs PORT
'use strict';
const net = require('net');
const Modbus = require('jsmodbus');

const port = Number(process.argv[2]);
const socket = new net.Socket();
const client = new Modbus.client.TCP(socket, 1, 2000);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const int32 = (hi, lo) => ((hi << 16) | lo) >> 0;

socket.on('error', (e) => {
  console.log(JSON.stringify({ error: String(e) }));
  process.exit(2);
});
socket.on('connect', async () => {
  try {
    const out = {};
    const first = (await client.readInputRegisters(0, 18)).response.body.valuesAsArray;
    out.map_version = first[0];
    out.motion_before = first[1];
    out.homed_before = (first[3] & 1) === 1;
    const seq = (first[4] + 1) & 0xffff;
    await client.writeMultipleRegisters(0, [1, seq, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    let regs = first;
    for (let i = 0; i < 200; i++) {
      regs = (await client.readInputRegisters(0, 18)).response.body.valuesAsArray;
      if (regs[1] === 3) break;  // holding
      await sleep(10);
    }
    out.motion_after = regs[1];
    out.homed_after = (regs[3] & 1) === 1;
    out.ack_seq = regs[4];
    out.sent_seq = seq;
    out.x_um = int32(regs[5], regs[6]);
    out.y_um = int32(regs[7], regs[8]);
    out.z_um = int32(regs[9], regs[10]);
    await client.writeSingleRegister(14, 1);
    const stopped = (await client.readInputRegisters(0, 18)).response.body.valuesAsArray;
    out.motion_after_stop = stopped[1];
    console.log(JSON.stringify(out));
    socket.end();
    process.exit(0);
  } catch (e) {
    console.log(JSON.stringify({ error: String(e && e.message ? e.message : e) }));
    process.exit(1);
  }
});
socket.connect({ host: '127.0.0.1', port });
