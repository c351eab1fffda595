// checks: normal { } perturbations (gradient rotated and non-uniformly scaled, onion, leopard,
// radial with frequency and triangle_wave, spherical, wood), their depth with
// bump_size and accuracy, a slope_map, and a reflective floor whose perturbed mirror rays would dip below it
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }
camera { location <0, 2, -7> look_at <0, 0.5, 0> right x*image_width/image_height angle 55 }
light_source { <-5, 8, -6> color rgb 1 }
light_source { <6, 4, -3> color rgb 0.5 }
background { rgb <0.2, 0.3, 0.5> }
plane { y, -1
  pigment { checker rgb 1 rgb 0.2 }
  finish { reflection 0.3 }
  normal { gradient x 0.4 sine_wave scale <0.7, 1, 2> rotate y*30 }
}
sphere { <-2.2, 0.2, 0>, 1 pigment { rgb <1, 0.3, 0.2> } finish { phong 0.8 } normal { onion 0.6 scale 0.2 } }
sphere { <0, 0.2, 0>, 1 pigment { rgb <0.3, 1, 0.3> } finish { specular 0.6 reflection 0.2 }
  normal { leopard bump_size 1.5 scale 0.15 } }
sphere { <2.2, 0.2, 0>, 1 pigment { rgb <0.4, 0.5, 1> } normal { radial 0.8 frequency 12 triangle_wave accuracy 0.01 } }
sphere { <-1, 1.9, 1.5>, 0.7 pigment { rgb <1, 1, 0.3> }
  normal { spherical 1 slope_map { [0 <0, 1>] [0.5 <1, 1>] [0.5 <1, -1>] [1 <0, -1>] } scale 0.3 } }
sphere { <1, 1.9, 1.5>, 0.7 pigment { rgb <0.9, 0.9, 0.9> } normal { wood 0.5 scale 0.2 rotate x*60 } }
