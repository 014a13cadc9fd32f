"""The station composed with parts of its own: the arm's base on a stand that lowers it
towards the demo mug while a trajectory curls the arm down, and a system that reports the
touches (the station's tactile skin) as they come. Drake's own systems (TrajectorySource)
and the user's (Stand, TouchReport) connect to the station's ports like any other."""
import numpy as np
from pydrake.all import (
    AbstractValue,
    DiagramBuilder,
    LeafSystem,
    PiecewisePolynomial,
    RigidTransform,
    RotationMatrix,
    Simulator,
    TrajectorySource,
)

from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig
from drake_continuum.station import make_station


class Stand(LeafSystem):
    """The arm's base, lowered from X_WB0 at `speed` m/s: output base_pose."""

    def __init__(self, X_WB0: RigidTransform, speed: float):
        super().__init__()
        self.X_WB0, self.speed = X_WB0, speed
        self.DeclareAbstractOutputPort("base_pose", lambda: AbstractValue.Make(X_WB0),
                                       self.calc)

    def calc(self, context, output):
        output.set_value(RigidTransform([0, 0, -self.speed * context.get_time()]) @ self.X_WB0)


class TouchReport(LeafSystem):
    """Prints the touches (regions, their sections, total area) every `period` s."""

    def __init__(self, period: float):
        super().__init__()
        self.touches = self.DeclareAbstractInputPort("touches", AbstractValue.Make(None))
        self.DeclarePeriodicPublishEvent(period, 0.0, self.report)

    def report(self, context):
        t = self.touches.Eval(context)
        print(f"t = {context.get_time():.2f} s: {len(t)} touches, sections "
              f"{sorted(set(t.section.tolist()))}, area {1e4 * t.area.sum():.2f} cm^2")


config, builder = load_config(), DiagramBuilder()
station = builder.AddSystem(make_station(config, object_mesh=MODELS_DIR / "mug.obj",
                                         camera=False))
arm = station.arm  # its base points along +x; its x axis, where phi = 0 bends, is down
X_WB0 = RigidTransform(RotationMatrix(arm.base_rotation), arm.base_position + [0, 0, 0.11])
straight = ArmConfig([0.12, 0.12, 0.12], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
curled = ArmConfig([0.12, 0.12, 0.12], [0.0, 3.0, 6.0], [0.0, 0.0, 0.0])
curl = builder.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(
    [0.0, 2.0], np.stack([straight.as_vector(), curled.as_vector()], axis=1))))
stand = builder.AddSystem(Stand(X_WB0, speed=0.02))
report = builder.AddSystem(TouchReport(period=0.25))
builder.Connect(curl.get_output_port(), station.GetInputPort("arm_configuration"))
builder.Connect(stand.get_output_port(), station.GetInputPort("base_pose"))
builder.Connect(station.GetOutputPort("touches"), report.get_input_port())
Simulator(builder.Build()).AdvanceTo(2.0)
