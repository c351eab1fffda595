// Soft shadows from a square area light (deterministic grid: no jitter; adaptive 100 samples every
// grid point, as our renderer does). The benchmarks rewrite the "9, 9" sample counts.
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-3, 6, -2> color rgb 1 area_light <2.5, 0, 0>, <0, 0, 2.5>, 9, 9 adaptive 100 }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <0, 0.8, 0>, 0.6 pigment { rgb <0.9, 0.5, 0.3> } finish { ambient 0.1 diffuse 0.7 } }
box { <0.8, 0, -0.4>, <1.3, 1.2, 0.2> pigment { rgb <0.4, 0.6, 0.9> } finish { ambient 0.1 diffuse 0.7 } }
cylinder { <-1.4, 0, 0.6>, <-1.4, 1.5, 0.6>, 0.2 pigment { rgb <0.5, 0.8, 0.4> } finish { ambient 0.1 diffuse 0.7 } }
