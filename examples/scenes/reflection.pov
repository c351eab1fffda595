// checks: reflection constant, min/max with falloff, and fresnel (ior 1.5) on opaque spheres
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.2, 0.25, 0.3> } finish { ambient 0.15 diffuse 0.6 } }
background { rgb <0.3, 0.4, 0.6> }
sphere { <-1.2, 0.5, 0>, 0.5 pigment { rgb <0.1, 0.1, 0.1> } finish { ambient 0 diffuse 0.3 reflection 0.7 } }
sphere { <0, 0.5, 0>, 0.5 pigment { rgb <0.1, 0.1, 0.1> } finish { ambient 0 diffuse 0.3 reflection { 0.05, 0.9 falloff 2 } } }
sphere { <1.2, 0.5, 0>, 0.5 pigment { rgb <0.1, 0.1, 0.1> } finish { ambient 0 diffuse 0.3 reflection { 0, 1 fresnel on } } interior { ior 1.5 } }
