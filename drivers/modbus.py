"""Modbus TCP / RTU capture driver: poll the DAQ's capture buffer and download whole captures.

The DAQ triggers itself and holds one capture in registers (``drivers.modbus_map``). The driver
polls the header; when a capture is ready it downloads the payload in reads of at most 125
registers, checks the length and the CRC-32 and yields the capture as ONE ``SampleBlock`` flagged
``capture``. The DAQ's buffer is acknowledged (freed) only when the consumer calls ``release()``
after the capture is durable, or asks for the next capture: a crash in between leaves the capture
in the DAQ, to be downloaded again, never lost. A timeout or an exception
response is retried a bounded number of times; after that the download is abandoned (no half
capture is ever yielded) and the whole capture is fetched again on the next poll.
"""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass

from pymodbus import FramerType
from pymodbus.client import AsyncModbusSerialClient, AsyncModbusTcpClient
from pymodbus.exceptions import ModbusException

from . import modbus_map as mm
from .errors import CaptureDownloadError
from .backoff import Backoff
from .interface import DriverStats, SampleBlock
from .pymodbus_logging import quiet_pymodbus
from .scaling import ChannelScaling

log = logging.getLogger("drivers.modbus")

CAPTURE_FLAG = "capture"


@dataclass(frozen=True)
class ModbusSettings:
    """How to reach a Modbus DAQ.

    Attributes
    ----------
    transport : {"tcp", "rtu"}
        Modbus TCP (MBAP framing) or RTU framing over a serial line or ``socket://host:port``.
    host, port : str, int
        Modbus TCP address.
    url : str
        RTU: serial device path or pyserial URL ``socket://host:port``.
    baudrate : int
        RTU serial line [bit/s].
    device_id : int
        Modbus unit/device id of the DAQ.
    timeout_s : float
        Response timeout per request [s].
    poll_interval_s : float
        Time between status polls when no capture is ready [s].
    block_retries : int
        Retries of one failed read before the capture download is abandoned.
    settle_s : float or None
        Quiet time after a timeout before retrying, so a late reply is not taken for the next
        one (RTU has no transaction id) [s]; None = ``timeout_s``.
    max_block_registers : int
        Registers per read, ≤ 125.
    reconnect_min_s, reconnect_max_s : float
        Backoff between connection attempts [s].
    """

    transport: str = "tcp"
    host: str = "127.0.0.1"
    port: int = 502
    url: str = ""
    baudrate: int = 115200
    device_id: int = 1
    timeout_s: float = 1.0
    poll_interval_s: float = 0.2
    block_retries: int = 3
    settle_s: float | None = None
    max_block_registers: int = mm.MAX_READ_REGISTERS
    reconnect_min_s: float = 0.1
    reconnect_max_s: float = 5.0

    def __post_init__(self):
        if self.transport not in ("tcp", "rtu"):
            raise ValueError(f"Modbus transport must be 'tcp' or 'rtu', got {self.transport!r}")
        if self.transport == "rtu" and not self.url:
            raise ValueError("Modbus RTU needs a serial device path or socket://host:port URL")
        if not 0 <= self.device_id <= 247:
            raise ValueError(f"Modbus device id must be 0..247, got {self.device_id}")
        if not 1 <= self.max_block_registers <= mm.MAX_READ_REGISTERS:
            raise ValueError(f"max_block_registers must be 1..{mm.MAX_READ_REGISTERS}")
        if self.timeout_s <= 0 or self.poll_interval_s <= 0 or self.block_retries < 0:
            raise ValueError("Modbus timeout and poll interval must be positive, retries >= 0")

    @property
    def where(self) -> str:
        """The address for log messages."""
        return f"tcp://{self.host}:{self.port}" if self.transport == "tcp" else f"rtu {self.url}"


def make_client(settings: ModbusSettings):
    """A pymodbus async client without its own retries or reconnects (the driver owns both)."""
    quiet_pymodbus()
    if settings.transport == "tcp":
        return AsyncModbusTcpClient(settings.host, port=settings.port, timeout=settings.timeout_s,
                                    retries=0, reconnect_delay=0)
    return AsyncModbusSerialClient(settings.url, framer=FramerType.RTU, baudrate=settings.baudrate,
                                   timeout=settings.timeout_s, retries=0, reconnect_delay=0)


class ModbusCaptureDriver:
    """Driver for a capture-buffer DAQ: ``async for capture_block in driver``.

    ``stats``: ``captures`` downloaded, ``retries`` of single reads, ``crc_errors`` (captures
    whose payload CRC failed), ``abandoned`` downloads, ``reconnects``, ``samples``.
    """

    def __init__(self, settings: ModbusSettings, scaling: ChannelScaling | None = None, *,
                 client=None, sleep=asyncio.sleep):
        self.settings = settings
        self.scaling = scaling or ChannelScaling()
        self.stats = DriverStats()
        self.client = client if client is not None else make_client(settings)
        self._sleep = sleep
        self._closed = False
        self._delivered = None  # (capture id, first index, crc) of the last capture yielded
        self._unreleased: mm.CaptureHeader | None = None  # yielded, not yet acknowledged
        self._ever_connected = False
        self._backoff = Backoff(settings.reconnect_min_s, settings.reconnect_max_s)

    def __aiter__(self):
        return self

    async def aclose(self) -> None:
        """Stop polling and close the connection."""
        self._closed = True
        self.client.close()
        self.stats.connected = False

    async def release(self) -> None:
        """Acknowledge the capture last yielded: call once it is durable; the DAQ then frees it."""
        header, self._unreleased = self._unreleased, None
        if header is not None and not self._closed:
            await self._acknowledge(header)

    async def __anext__(self) -> SampleBlock:
        s = self.settings
        if self._unreleased is not None:  # asking for more means the last one was handled
            await self.release()
        while not self._closed:
            if not await self._ensure_connected():
                continue
            try:
                header = mm.decode_header(await self._read(0, mm.HEADER_REGISTERS))
            except (CaptureDownloadError, mm.RegisterMapError) as exc:
                log.warning("Modbus DAQ %s: status poll failed: %s", s.where, exc)
                await self._sleep(s.poll_interval_s)
                continue
            if not header.ready:
                await self._sleep(s.poll_interval_s)
                continue
            key = (header.capture_id, header.first_sample_index, header.payload_crc32)
            if key == self._delivered:  # delivered before, but the acknowledgement was lost
                await self._acknowledge(header)
                continue
            try:
                block = await self._download(header)
            except CaptureDownloadError as exc:
                self.stats.abandoned += 1
                log.warning("Modbus DAQ %s: capture %d abandoned, retrying on the next poll: %s",
                            s.where, header.capture_id, exc)
                await self._sleep(s.poll_interval_s)
                continue
            self._delivered = key
            self._unreleased = header
            self.stats.captures += 1
            self.stats.samples += block.travel.size
            return block
        raise StopAsyncIteration

    async def _ensure_connected(self) -> bool:
        if self.client.connected:
            return True
        self.stats.connected = False
        if await self.client.connect():
            if self._ever_connected:
                self.stats.reconnects += 1
            self._ever_connected = True
            self._backoff.reset()
            self.stats.connected = True
            log.info("Modbus DAQ %s: connected", self.settings.where)
            return True
        wait = self._backoff.next()
        log.warning("Modbus DAQ %s: cannot connect; next attempt in %.1f s", self.settings.where, wait)
        await self._sleep(wait)
        return False

    async def _read(self, address: int, count: int) -> list[int]:
        """One read of holding registers with bounded retries (each retry is counted)."""
        s = self.settings
        error = "no attempt"
        for attempt in range(1 + s.block_retries):
            if self._closed:
                break
            if attempt:
                self.stats.retries += 1
            try:
                rr = await self.client.read_holding_registers(address, count=count, device_id=s.device_id)
            except ModbusException as exc:  # timeout or lost connection
                error = f"no valid reply ({exc})"
                await self._sleep(s.settle_s if s.settle_s is not None else s.timeout_s)
                continue
            if rr.isError():
                error = f"exception response {getattr(rr, 'exception_code', '?')}"
                await self._sleep(min(s.poll_interval_s, s.timeout_s))
                continue
            if len(rr.registers) != count:
                error = f"asked for {count} registers at {address}, got {len(rr.registers)}"
                continue
            return list(rr.registers)
        raise CaptureDownloadError(f"read of {count} registers at {address} failed "
                                   f"after {1 + s.block_retries} attempts: {error}")

    async def _download(self, header: mm.CaptureHeader) -> SampleBlock:
        regs: list[int] = []
        for address, count in mm.block_reads(header.payload_registers,
                                             max_count=self.settings.max_block_registers):
            regs += await self._read(address, count)
        if len(regs) != header.payload_registers:
            raise CaptureDownloadError(f"downloaded {len(regs)} registers, header announces "
                                       f"{header.payload_registers}")
        codes = mm.decode_payload(regs, header.channels)
        if mm.payload_crc32(codes) != header.payload_crc32:
            self.stats.crc_errors += 1
            raise CaptureDownloadError("payload CRC-32 does not match the header")
        sc = self.scaling
        return SampleBlock(header.first_sample_index, sc.code_to_travel(codes[:, 0]),
                           sc.code_to_vibration(codes[:, 1]), float(header.sample_rate_hz),
                           frozenset({CAPTURE_FLAG}))

    async def _acknowledge(self, header: mm.CaptureHeader) -> None:
        try:
            rr = await self.client.write_register(mm.ACK, header.capture_id, device_id=self.settings.device_id)
            if rr.isError():
                raise ModbusException(f"exception response {getattr(rr, 'exception_code', '?')}")
        except ModbusException as exc:
            # The capture is already verified and yielded; the next poll acknowledges again.
            log.warning("Modbus DAQ %s: acknowledging capture %d failed: %s", self.settings.where,
                        header.capture_id, exc)
