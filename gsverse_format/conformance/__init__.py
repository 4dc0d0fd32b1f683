"""Engine-plugin conformance suite for ``GSVERSE_gaussian_splatting_mesh_anchor``.

* :mod:`.export` writes the suite (``gsverse-conformance export DIR``): GLB assets, poses as
  raw float32 vertex arrays, float64 reference outputs and a JSON manifest per case;
* :mod:`.check` reads a plugin's result dumps and reports per case
  (``gsverse-conformance check DIR RESULTS``);
* :mod:`.harness` runs a remap implementation over the suite and writes its dumps, as an
  engine harness does (the library's own implementations use it);
* :mod:`.minimal_reader` is the importer logic a plugin needs, written without any glTF
  library (the checks that make a plugin refuse an invalid asset included).

The dump layout and the tolerances are described in ``spec/conformance.md``.
"""
