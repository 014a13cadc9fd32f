"""The arm, its touch and its camera as a Drake Diagram (make_station), and Algorithm 1 as a
controller that a Simulator runs (WrapController). docs/station.md draws the diagram."""

from ._camera import KinectNoise, add_camera
from ._controller import WrapController
from ._station import ArmPoser, Station, TouchPins, TouchSensor, make_station

__all__ = ["ArmPoser", "KinectNoise", "Station", "TouchPins", "TouchSensor", "WrapController",
           "add_camera", "make_station"]
