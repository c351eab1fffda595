// checks: a difference's subtracted surface faces into the cavity (hollow glass: rays leave the glass through the inner wall, with interior fade)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 6 }
camera { location <0, 0.6, -4> look_at <0, 0.1, 0> right x*image_width/image_height angle 45 }
light_source { <-5, 10, -10> color rgb 1 }
plane { z, 3 pigment { checker rgb <1, 0.25, 0.2> rgb <0.2, 0.3, 1> scale 0.5 } finish { ambient 0.3 diffuse 0.6 } }
plane { y, -1.2 pigment { rgb 0.8 } finish { ambient 0.2 diffuse 0.6 } }
difference {
  sphere { 0, 1 }
  sphere { 0, 0.8 }
  box { <-2, 0.5, -2>, <2, 2, 2> }
  pigment { rgbf <0.9, 1, 0.9, 0.95> }
  finish { ambient 0 diffuse 0.05 phong 0.5 reflection 0.05 }
  interior { ior 1.5 fade_distance 0.5 fade_power 2 fade_color <0.2, 0.6, 0.3> }
}
