"""Handing a block to reconstruction: COLMAP (through pycolmap), OpenDroneMap, NodeODM, Metashape
and Pix4D projects, COLMAP's field quick-look, and accuracy at ground control and check points.

Modules: errors, intrinsics (camera intrinsics from the database or EXIF), block (the frames,
their cameras and pose priors), pairs (image pairs from ground footprints), colmap_adapter (the
only code that knows pycolmap's API), colmap_project (the COLMAP database and pairs file),
quicklook (``--run``), report (report.json / report.html), control (GCPs against a model),
odm and reference (ODM, Metashape and Pix4D files), nodeodm (a NodeODM node through pyodm).
"""
