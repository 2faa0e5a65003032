"""Test-data generators shared by the examples, tests and benchmarks: 2D clouds and images of a
sheet, rasterised and rendered solids, range clouds of a moving solid. The demo's own sheet
generator is :mod:`refine.demo_data` (in the library)."""
