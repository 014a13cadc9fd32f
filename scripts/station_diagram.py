"""Draw the station with a WrapController as docs/images/station.png (Drake's graphviz
string, rendered by graphviz's dot)."""

import shutil
import subprocess
import sys
from pathlib import Path

from pydrake.systems.framework import DiagramBuilder

from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import MODELS_DIR
from drake_continuum.station import WrapController, make_station
from drake_continuum.wrapping.planes import enumerate_planes

OUT = Path(__file__).resolve().parents[1] / "docs" / "images" / "station.png"

if shutil.which("dot") is None:
    sys.exit("station_diagram: graphviz's dot is not installed (apt-get install graphviz)")
config, builder = load_config(), DiagramBuilder()
station = builder.AddSystem(make_station(config, object_mesh=MODELS_DIR / "mug.obj"))
WrapController.AddToBuilder(builder, station, params=config.wrap,
                            plane=enumerate_planes(station.arm.base_position)[1])
dot = builder.Build().GetGraphvizString(max_depth=2)
subprocess.run(["dot", "-Tpng", "-Gdpi=80", "-o", str(OUT)], input=dot.encode(), check=True)
print(OUT)
