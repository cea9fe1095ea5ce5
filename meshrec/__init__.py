"""meshrec: recognise a touched object, and where it was touched, from three probe curves.

The method is that of "Surface Recognition by Registering Data Curves from Touch", on
meshes: the curves' local geometry (normal, Gaussian and mean curvature) is looked up in
each model's per-vertex curvature table for candidate contacts, and a local search on
surface charts finds the superposition with the least point-to-surface error.

Typical use::

    import meshrec
    library = meshrec.ModelLibrary.from_folder("my_models/")
    touch = meshrec.TouchData.from_file("touch.csv")
    result = meshrec.recognize(touch, library)
    print(result.best.model, result.best.contact, result.best.T_model_touch)
"""

from meshrec._version import __version__
from meshrec.contact.geometry import (
    CommonPoint,
    LocalGeometry,
    RoughFitWarning,
    estimate_local_geometry,
    find_common_point,
)
from meshrec.io.touch import TouchData
from meshrec.model.index import IndexParams, ModelIndex
from meshrec.model.library import ModelLibrary, bundled_models_dir
from meshrec.model.mesh import load_mesh
from meshrec.recognition.recognize import Recognition, recognize
from meshrec.recognition.scoring import VERDICTS, ModelScore, PoseHypothesis, Verdict
from meshrec.registration.candidates import curvature_tolerance
from meshrec.registration.register import Registration, StageTimes, refine_pose, register
from meshrec.sim.paper import PAPER_SURFACES, localisation_error, symmetry_rotations
from meshrec.sim.simulate import SimulatedTouch, simulate_touch

__all__ = [
    "PAPER_SURFACES",
    "VERDICTS",
    "CommonPoint",
    "IndexParams",
    "LocalGeometry",
    "ModelIndex",
    "ModelLibrary",
    "ModelScore",
    "PoseHypothesis",
    "Recognition",
    "Registration",
    "RoughFitWarning",
    "SimulatedTouch",
    "StageTimes",
    "TouchData",
    "Verdict",
    "__version__",
    "bundled_models_dir",
    "curvature_tolerance",
    "estimate_local_geometry",
    "find_common_point",
    "load_mesh",
    "localisation_error",
    "recognize",
    "refine_pose",
    "register",
    "simulate_touch",
    "symmetry_rotations",
]
