// Lambert scene that Mitsuba 3 matches exactly (reference §6.3): one parallel light, diffuse-only
// spheres and boxes (brilliance 1, ambient 0) on a checker plane, black background.
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.3, 2.2, -6.0> look_at <0, 0.6, 0> right x*image_width/image_height angle 50 }
light_source { <-3, 6, -4> color rgb <1, 0.97, 0.9> parallel point_at <0, 0, 0> }
plane { y, 0
  pigment { checker rgb <0.8, 0.8, 0.75>, rgb <0.25, 0.3, 0.35> }
  finish { ambient 0 diffuse 0.9 } }
sphere { <-1.3, 0.8, 0.2>, 0.8 pigment { rgb <0.9, 0.35, 0.25> } finish { ambient 0 diffuse 0.85 } }
sphere { <0.6, 0.45, -0.9>, 0.45 pigment { rgb <0.3, 0.8, 0.35> } finish { ambient 0 diffuse 0.85 } }
box { <-0.6, 0, -0.6>, <0.6, 1.4, 0.6> rotate <0, 35, 0> translate <1.5, 0, 1.0>
  pigment { rgb <0.3, 0.45, 0.9> } finish { ambient 0 diffuse 0.85 } }
