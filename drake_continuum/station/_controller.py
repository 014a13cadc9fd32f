"""Algorithm 1 as a Drake controller: each discrete update is one enclosing or one advancing
motion of the same WrapStepper that `wrapping.wrap.wrap()` drives, so a simulated wrap and a
batch wrap are one implementation."""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import EventStatus, LeafSystem

from ..kinematics.arm import ArmConfig
from ..wrapping.contact import Contacts
from ..wrapping.planes import WrapPlane
from ..wrapping.scene import WrapScene
from ..wrapping.wrap import WrapParams, WrapPhase, WrapStepper
from ..wrapping.wrap_types import WrapResult

__all__ = ["WrapController"]


class WrapController(LeafSystem):
    """Reads the station's `touches`, writes its `arm_configuration` and `base_pose`.

    At initialization it starts the wrap (the start configuration of `plane`); then every
    `period` seconds it makes the next motion: an enclosing (curving sections until they
    touch, asking `scene` for contact at each step as Algorithm 1 does) or an advancing (from
    the `touches` it reads at the enclosed configuration, then IK). When the wrap has ended
    it reads the final configuration's touches, keeps the WrapResult (`result()`) and ends
    the simulation (EventStatus.ReachedTermination), so `Simulator.AdvanceTo` performs one
    wrap.

    The wrap in progress (a WrapStepper holding `scene`, which a context cannot copy) lives
    on the system: one controller runs one simulation at a time. Its context's state is
    what it outputs: the configuration (discrete) and the base pose (abstract).

    Args:
        scene: the contact scene the enclosing motions ask (the station's arm and object).
        plane: the wrap plane.
        params: Algorithm 1's parameters.
        period: simulated time between motions, s.
    """

    def __init__(self, *, scene: WrapScene, plane: WrapPlane,
                 params: WrapParams = WrapParams(), period: float = 0.05):
        super().__init__()
        self._scene, self._plane, self._params = scene, plane, params
        self._stepper: WrapStepper | None = None
        self._result: WrapResult | None = None
        arm = scene.arm
        rest = ArmConfig.straight(arm.section_limits()[0])
        self._touches = self.DeclareAbstractInputPort("touches",
                                                      AbstractValue.Make(Contacts.empty()))
        config = self.DeclareDiscreteState(rest.as_vector())
        base = self.DeclareAbstractState(AbstractValue.Make(
            RigidTransform(RotationMatrix(arm.base_rotation), arm.base_position)))
        self.DeclareStateOutputPort("arm_configuration", config)
        self.DeclareStateOutputPort("base_pose", base)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._start)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, period, self._step)

    @staticmethod
    def AddToBuilder(builder, station, *, plane: WrapPlane, params: WrapParams = WrapParams(),
                     scene: WrapScene | None = None, period: float = 0.05
                     ) -> "WrapController":
        """Add a controller to `builder` and connect it to `station` (a system of `builder`
        with the station's ports): touches in, arm_configuration and base_pose out. The
        scene defaults to the station's own (Station.scene())."""
        scene = station.scene() if scene is None else scene
        controller = builder.AddNamedSystem("wrap_controller", WrapController(
            scene=scene, plane=plane, params=params, period=period))
        builder.Connect(station.GetOutputPort("touches"), controller.get_input_port())
        for name in ("arm_configuration", "base_pose"):
            builder.Connect(controller.GetOutputPort(name), station.GetInputPort(name))
        return controller

    def set_plane(self, plane: WrapPlane) -> None:
        """Wrap in `plane` from the next initialization on (Simulator.Initialize)."""
        self._plane = plane

    def result(self) -> WrapResult | None:
        """The wrap, once the simulation has ended it (None before)."""
        return self._result

    def _start(self, context, state) -> None:
        self._result = None
        self._stepper = WrapStepper(self._scene, self._plane, self._params)
        self._write(state)

    def _step(self, context, state):
        stepper = self._stepper
        if self._result is not None:
            return EventStatus.ReachedTermination(self, "the wrap has ended")
        if stepper.done:
            self._result = stepper.result(self._touches.Eval(context))
            return EventStatus.ReachedTermination(self, f"wrap {self._result.status}")
        if stepper.phase is WrapPhase.kAdvance:
            stepper.advance(self._touches.Eval(context))
        else:
            stepper.enclose()
        self._write(state)
        return EventStatus.Succeeded()

    def _write(self, state) -> None:
        arm = self._scene.arm  # on the wrap's base while the wrap runs
        state.get_mutable_discrete_state(0).SetFromVector(self._stepper.config.as_vector())
        state.get_mutable_abstract_state(0).set_value(
            RigidTransform(RotationMatrix(arm.base_rotation), arm.base_position))
