"""Serial-port discovery: which ports exist and which of them probably carry a skin.

:func:`list_ports` wraps :func:`serial.tools.list_ports.comports` into plain
:class:`PortInfo` records.  ``likely_skin`` marks the USB vendors a skin controller
shows up as: Espressif's native USB (ESP32-S3 USB-Serial-JTAG / TinyUSB CDC) and the
common USB-UART bridges found on ESP32 development boards.
"""

from __future__ import annotations

from dataclasses import dataclass

from serial.tools import list_ports as _serial_list_ports

SKIN_USB_VENDORS: dict[int, str] = {
    0x303A: "Espressif (ESP32-S3 native USB)",
    0x10C4: "Silicon Labs CP210x",
    0x1A86: "WCH CH34x",
    0x0403: "FTDI",
}
"""USB vendor ids of the controllers and bridges a skin is usually attached through."""


@dataclass(frozen=True)
class PortInfo:
    """One serial port as the OS reports it."""

    device: str
    description: str = ""
    hwid: str = ""
    vid: int | None = None
    pid: int | None = None
    serial_number: str | None = None
    manufacturer: str | None = None
    likely_skin: bool = False

    @property
    def vendor(self) -> str:
        """A readable vendor name for known skin vendors, else ``""``."""
        return SKIN_USB_VENDORS.get(self.vid, "") if self.vid is not None else ""


def is_likely_skin(vid: int | None) -> bool:
    return vid in SKIN_USB_VENDORS


def list_ports() -> list[PortInfo]:
    """All serial ports, likely skins first, then by device name."""
    ports = [
        PortInfo(
            device=p.device,
            description=p.description or "",
            hwid=p.hwid or "",
            vid=p.vid,
            pid=p.pid,
            serial_number=p.serial_number,
            manufacturer=p.manufacturer,
            likely_skin=is_likely_skin(p.vid),
        )
        for p in _serial_list_ports.comports()
    ]
    return sorted(ports, key=lambda p: (not p.likely_skin, p.device))
