"""The device package's rooms: each module small enough to read, each class too, and every name
importable from ``omni_sim.device`` the rooms' own object."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import omni_sim.device
from omni_sim.device import core, encoder, engine, laws, parameters

ROOM = Path(omni_sim.device.__file__).resolve().parent
ROOMS = sorted(ROOM.glob("*.py"))
#: The ceilings of a room and of a class in it [lines].
MAX_MODULE_LINES = 700
MAX_CLASS_LINES = 300


@pytest.mark.parametrize("path", ROOMS, ids=lambda p: p.name)
def test_rooms_and_their_classes_are_small(path):
    text = path.read_text()
    assert len(text.splitlines()) <= MAX_MODULE_LINES
    for node in ast.parse(text).body:
        if isinstance(node, ast.ClassDef):
            assert node.end_lineno - node.lineno + 1 <= MAX_CLASS_LINES, node.name


def test_every_name_is_the_rooms_own():
    """The package re-exports the rooms' objects themselves (not copies): ``omni_sim.device.X``
    is the object the engine and the device use."""
    for name in omni_sim.device.__all__:
        obj = getattr(omni_sim.device, name)
        homes = [m for m in (core, encoder, engine, laws) if getattr(m, name, None) is obj]
        assert homes, name
    assert omni_sim.device.DRIVE_LAWS is laws.DRIVE_LAWS  # register_drive_law adds to the one registry
    assert omni_sim.device._numeric is laws._numeric and omni_sim.device._DriveLaws is laws._DriveLaws


def test_the_device_holds_its_parameters():
    """The named parameters are the device's own methods (its base class), not a second object."""
    assert issubclass(omni_sim.device.Device, parameters.DeviceParameters)
    for name in ("yaw_damping", "yaw_frictionloss", "body", "set_body", "servo_gain", "set_servo_gain",
                 "lugre", "set_lugre", "friction_actuator", "lugre_actuators", "friction",
                 "friction_family", "scale_friction"):
        assert hasattr(omni_sim.device.Device, name), name
