"""Modbus DAQ emulator: pymodbus's own server holding captures in the register map.

Captures are queued and served one at a time: the header says ``ready``; when the client writes
the capture id to the ACK register the next capture is loaded (or the status goes empty).
Served over Modbus TCP, or with RTU framing on a TCP socket (clients use pyserial's
``socket://host:port``). Faults for tests: a late reply (longer than the client's timeout) and
an exception response, both on a chosen payload read.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from .. import modbus_map as mm
from ..interface import SampleBlock
from ..pymodbus_logging import quiet_pymodbus
from ..scaling import ChannelScaling

log = logging.getLogger("drivers.emulators.modbus")


@dataclass
class ModbusEmulatorStats:
    """What the emulator did, to compare with the driver's ``DriverStats``."""

    captures_loaded: int = 0
    captures_acknowledged: int = 0
    reads: int = 0
    payload_reads: int = 0
    delays_injected: int = 0
    exceptions_injected: int = 0
    bad_acks: int = 0


@dataclass(frozen=True)
class ServedCapture:
    """A capture as the emulator holds it: the exact codes a correct download must return."""

    capture_id: int
    first_sample_index: int
    sample_rate_hz: int
    codes: np.ndarray  # int16, shape (samples, 2)


class ModbusDaqEmulator:
    """A capture-buffer DAQ on a pymodbus server.

    Parameters
    ----------
    captures : iterable of SampleBlock
        Physical units; converted to codes with ``scaling``.
    transport : {"tcp", "rtu"}
        ``rtu``: RTU framing on a TCP socket (``socket://host:port``).
    host, port : str, int
        Listen address; port 0 picks a free port.
    device_id : int
    """

    def __init__(self, captures: Iterable[SampleBlock], *, transport: str = "tcp",
                 scaling: ChannelScaling | None = None, host: str = "127.0.0.1", port: int = 0,
                 device_id: int = 1):
        if transport not in ("tcp", "rtu"):
            raise ValueError(f"transport must be 'tcp' or 'rtu', got {transport!r}")
        self.transport = transport
        self.scaling = scaling or ChannelScaling()
        self.host, self.port = host, port
        self.device_id = device_id
        self.stats = ModbusEmulatorStats()
        self.served: list[ServedCapture] = []  # loaded captures, in order (the truth for tests)
        self._queue: deque[ServedCapture] = deque()
        self._next_id = 1
        self._current: ServedCapture | None = None
        self._faults: list[list] = []  # [payload reads to wait, kind, argument]
        self._registers: list[int] | None = None
        self._server = None
        for block in captures:
            self.add_capture(block)

    def add_capture(self, block: SampleBlock) -> ServedCapture:
        """Queue a capture; returns what a correct download must reproduce."""
        codes = np.column_stack([self.scaling.travel_to_code(block.travel),
                                 self.scaling.vibration_to_code(block.vibration)])
        if codes.size > mm.MAX_PAYLOAD_REGISTERS:
            raise ValueError(f"capture of {block.travel.size} samples exceeds the register buffer "
                             f"({mm.MAX_PAYLOAD_REGISTERS // 2} samples)")
        cap = ServedCapture(self._next_id & 0xFFFF, block.first_sample_index, int(round(block.sample_rate)), codes)
        self._next_id += 1
        self._queue.append(cap)
        if self._registers is not None and self._current is None:
            self._load_next()
        return cap

    # -- faults ---------------------------------------------------------------------------------
    def inject_delay(self, delay_s: float, *, at_read: int = 3) -> None:
        """Answer the ``at_read``-th payload read from now ``delay_s`` late [s]."""
        self._faults.append([at_read, "delay", delay_s])

    def inject_exception(self, *, at_read: int = 3, code: ExcCodes = ExcCodes.DEVICE_BUSY) -> None:
        """Answer the ``at_read``-th payload read from now with an exception response."""
        self._faults.append([at_read, "exception", code])

    # -- server ---------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """Where the driver connects: ``tcp://host:port`` or (RTU) ``socket://host:port``."""
        return f"{'tcp' if self.transport == 'tcp' else 'socket'}://{self.host}:{self.port}"

    async def start(self) -> str:
        """Start serving; returns ``url`` (with the real port when port 0 was asked for)."""
        quiet_pymodbus()
        device = SimDevice(self.device_id, simdata=[SimData(0, count=mm.REGISTER_SPACE, values=0,
                                                            datatype=DataType.REGISTERS)],
                           action=self._action)
        if self.transport == "tcp":
            self._server = ModbusTcpServer(device, address=(self.host, self.port))
        else:
            self._server = ModbusSerialServer(device, framer=FramerType.RTU,
                                              port=f"socket://{self.host}:{self.port}")
        await self._server.serve_forever(background=True)
        self.port = self._server.transport.sockets[0].getsockname()[1]
        log.info("Modbus DAQ emulator (%s, device id %d): connect to %s", self.transport,
                 self.device_id, self.url)
        return self.url

    async def stop(self) -> None:
        if self._server is not None:
            await self._server.shutdown()
            self._server = None

    async def __aenter__(self):
        await self.start()
        return self

    async def __aexit__(self, *exc):
        await self.stop()

    def _load_next(self) -> None:
        regs = self._registers
        if not self._queue:
            self._current = None
            regs[mm.STATUS] = mm.STATUS_EMPTY
            regs[mm.MAP_VERSION_REG] = mm.MAP_VERSION
            return
        cap = self._current = self._queue.popleft()
        payload = mm.encode_payload(cap.codes)
        regs[mm.PAYLOAD_START:mm.PAYLOAD_START + len(payload)] = payload
        header = mm.CaptureHeader(mm.STATUS_READY, cap.capture_id, cap.codes.shape[1], cap.codes.shape[0],
                                  cap.first_sample_index, cap.sample_rate_hz, mm.payload_crc32(cap.codes))
        regs[:mm.HEADER_REGISTERS] = mm.encode_header(header)
        self.served.append(cap)
        self.stats.captures_loaded += 1

    async def _action(self, function_code, start_address, address, count, registers, set_values):
        """Called by the pymodbus server on every access, before it reads or writes ``registers``."""
        if self._registers is None:  # first access: adopt the server's register list, load
            self._registers = registers
            self._load_next()
        if set_values is not None:
            if address != mm.ACK or count != 1:
                return ExcCodes.ILLEGAL_ADDRESS  # only the ACK register is writable
            if self._current is not None and set_values[0] == self._current.capture_id:
                self.stats.captures_acknowledged += 1
                self._load_next()
            else:
                self.stats.bad_acks += 1
            return None
        self.stats.reads += 1
        if address < mm.PAYLOAD_START:
            return None
        self.stats.payload_reads += 1
        for fault in list(self._faults):
            fault[0] -= 1
            if fault[0] > 0:
                continue
            self._faults.remove(fault)
            if fault[1] == "delay":
                self.stats.delays_injected += 1
                await asyncio.sleep(fault[2])
            else:
                self.stats.exceptions_injected += 1
                return fault[2]
        return None
