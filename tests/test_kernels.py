"""After kernels.compile_all (what scripts/setup.sh runs), a fresh process that wraps, poses
the station, searches the conformity bound and recognises actively asks no kernel for a
layout compile_all did not make: every layout a run passes is in the disk cache, so no
worker pays seconds of compiling. (Counted by the versions each kernel holds, not by
numba's compile events, which a cache filled by earlier tests would hide.)"""
import json
import subprocess
import sys

from drake_continuum.kernels import compile_all
from synthetic_wraps import separable_objects, write_collection

RUN = r"""
import json, sys
from numba.core.registry import CPUDispatcher
from pydrake.math import RigidTransform, RotationMatrix
from drake_continuum.cli import main
from drake_continuum.config import load_config
from drake_continuum.kernels import compile_all
from drake_continuum.kinematics.arm import MODELS_DIR
from drake_continuum.station import make_station
from drake_continuum.wrapping.bound import BoundParams, best_wrap
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import wrap


def versions():
    return {f"{m}.{k}": set(d.signatures) for m, module in list(sys.modules.items())
            if m.startswith("drake_continuum") for k, d in vars(module).items()
            if isinstance(d, CPUDispatcher)}


wraps, model = sys.argv[1:3]
compile_all()
before = versions()
config = load_config()
arm = config.arm()
scene = WrapScene(arm, MODELS_DIR / "mug.obj")
plane = enumerate_planes(arm.base_position)[1]
done = wrap(scene, plane)
station = make_station(config, object_mesh=MODELS_DIR / "mug.obj", table=False, camera=False)
context = station.CreateDefaultContext()
station.GetInputPort("arm_configuration").FixValue(context, done.final_config.as_vector())
station.GetInputPort("base_pose").FixValue(
    context, RigidTransform(RotationMatrix(done.base_rotation), arm.base_position))
station.GetOutputPort("touches").Eval(context)
best_wrap(scene, plane, params=BoundParams(maxiter=2, polish=1))
assert main(["-q", "train-active", wraps, "--out", model]) == 0
assert main(["-q", "recognize", model, str(MODELS_DIR / "mug.obj"), "--json",
             "--set", "active.n_simulations=20"]) == 0
new = {k: sorted(map(str, v - before.get(k, set()))) for k, v in versions().items()}
print(json.dumps({k: v for k, v in new.items() if v}))
"""


def test_a_run_after_compile_all_compiles_no_kernel(tmp_path):
    assert compile_all(), "numba found no folder to cache its kernels in"
    wraps = tmp_path / "wraps"
    write_collection(wraps, separable_objects(4, 3))
    out = subprocess.run([sys.executable, "-c", RUN, str(wraps), str(tmp_path / "model")],
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out.strip().splitlines()[-1]) == {}
