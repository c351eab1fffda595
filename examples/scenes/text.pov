// checks: text in POV-Ray's fonts (kerning, offset, an internal font), engraved in a box by CSG difference, with shadows
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <1.6, 1.2, -3.6> look_at <1.6, 0.2, 0> right x*image_width/image_height angle 60 }
light_source { <-10, 20, -15> color rgb 1 }
light_source { <10, 10, -5> color rgb 0.4 }
plane { y, -0.3 pigment { rgb 0.6 } }
text { ttf "timrom.ttf" "AVo Ray!" 0.3, 0 pigment { rgb <1, 0.3, 0.2> } }
text { internal 2 "WAVE" 0.2, <0.05, 0.02, 0> rotate -20*y translate <0, 0.8, 0.8> pigment { rgb <0.2, 0.5, 1> } }
difference {
  box { <-0.2, -0.3, -1.2>, <3.4, -0.1, -0.6> }
  text { ttf "crystal.ttf" "engraved" 0.3, 0 scale 0.5 rotate 90*x translate <0.1, -0.05, -1.05> }
  pigment { rgb <0.9, 0.85, 0.6> }
}
