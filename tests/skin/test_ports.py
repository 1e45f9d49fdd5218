"""Tests for serial-port discovery (the OS port list is replaced by fixed entries)."""

from __future__ import annotations

import pytest
from serial.tools.list_ports_common import ListPortInfo

from wovenskin.skin import ports
from wovenskin.skin.ports import PortInfo, list_ports


def _port(device: str, vid: int | None = None, pid: int | None = None, **extra) -> ListPortInfo:
    info = ListPortInfo(device, skip_link_detection=True)
    info.vid, info.pid = vid, pid
    for key, value in extra.items():
        setattr(info, key, value)
    return info


@pytest.fixture
def fake_ports(monkeypatch):
    entries = [
        _port("/dev/ttyS0"),
        _port("/dev/ttyUSB1", 0x0403, 0x6001, description="FT232R USB UART"),
        _port(
            "/dev/ttyACM0",
            0x303A,
            0x1001,
            description="USB JTAG/serial debug unit",
            hwid="USB VID:PID=303A:1001 SER=F4:12:FA:00:00:01",
            serial_number="F4:12:FA:00:00:01",
            manufacturer="Espressif",
        ),
        _port("/dev/ttyACM1", 0x2341, 0x0043, description="Arduino Uno"),
        _port("/dev/ttyUSB0", 0x10C4, 0xEA60, description="CP2102N USB to UART"),
        _port("/dev/ttyUSB2", 0x1A86, 0x7523, description="USB-SERIAL CH340"),
    ]
    monkeypatch.setattr(ports._serial_list_ports, "comports", lambda: entries)


def test_skin_vendors_are_flagged_and_listed_first(fake_ports):
    found = list_ports()
    assert [p.device for p in found] == [
        "/dev/ttyACM0",
        "/dev/ttyUSB0",
        "/dev/ttyUSB1",
        "/dev/ttyUSB2",
        "/dev/ttyACM1",
        "/dev/ttyS0",
    ]
    assert [p.likely_skin for p in found] == [True, True, True, True, False, False]


def test_port_details_are_carried_over(fake_ports):
    esp = next(p for p in list_ports() if p.device == "/dev/ttyACM0")
    assert esp == PortInfo(
        device="/dev/ttyACM0",
        description="USB JTAG/serial debug unit",
        hwid="USB VID:PID=303A:1001 SER=F4:12:FA:00:00:01",
        vid=0x303A,
        pid=0x1001,
        serial_number="F4:12:FA:00:00:01",
        manufacturer="Espressif",
        likely_skin=True,
    )
    assert "Espressif" in esp.vendor
    plain = next(p for p in list_ports() if p.device == "/dev/ttyS0")
    assert plain.vid is None and plain.vendor == "" and not plain.likely_skin


def test_no_ports(monkeypatch):
    monkeypatch.setattr(ports._serial_list_ports, "comports", lambda: [])
    assert list_ports() == []
