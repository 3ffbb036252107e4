"""Geometry: calibration files (:mod:`.calibration`), rectification (:mod:`.rectify`), rig corrections
(:mod:`.rigcorrect`), the disparity-to-depth model (:mod:`.depth`, :mod:`.depth_file`), point clouds
(:mod:`.pointcloud`), dense disparity images (:mod:`.disparity_maps`), the overlay of the two cameras
(:mod:`.overlay`), which geometry source wins when several are given (:mod:`.source`) and the thesis rig
(:mod:`.rig`).
"""

__all__: list[str] = []  # the names live in the modules; import them from there
