"""The physics core: media, the RFT element law and its kernels, surface elements, rigid bodies.

Pure functions over arrays in SI units; imports no mujoco, rerun, plotting or CLI code
(``tests/test_layers.py`` enforces it). Modules, in dependency order:

* ``units``: named conversions at the boundary (N/cm^3, cm, mm, deg);
* ``material``: the 2D coefficient models alpha(beta, gamma), their scale zeta, presets;
* ``law``: constants of the 3D element law (frame switch, scaling functions f1, f23);
* ``surface``, ``soil``, ``agarwal``, ``quadrature``, ``patches``: the free surface and the
  deforming ground, the second force model's parameters, the surface quadrature's data;
* ``engine``: the C++ engine library through ctypes: its kernel (element forces, body wrenches,
  trajectories) and surfaces, the evaluation of every medium given by coefficients;
* ``rft``: ``element_forces``, checked inputs, and the NumPy evaluation for callables;
* ``elements``, ``geometry``: surface triangles of primitives and checked meshes;
* ``body``: rigid bodies and prescribed trajectories.
"""
