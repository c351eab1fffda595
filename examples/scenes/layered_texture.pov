// checks: layered textures: a transparent checker decal over an opaque floor, a filtering gradient layer with specular and reflection over a reflective sphere
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0, 1.5, -5> look_at <0, 0.5, 0> right x*image_width/image_height angle 50 }
light_source { <-10, 20, -15> color rgb 1 }
background { color rgb <0.2, 0.3, 0.4> }
plane { y, 0 texture { pigment { rgb <0.8, 0.8, 0.7> } finish { ambient 0.1 diffuse 0.7 } }
                texture { pigment { checker rgbt <0.9, 0.1, 0.1, 0.6>, rgbt <0, 0, 0, 1> } finish { ambient 0.2 diffuse 0.5 phong 0.5 } } }
sphere { <0, 1, 0>, 1
  texture { pigment { rgb <0.2, 0.4, 0.9> } finish { ambient 0.1 diffuse 0.6 reflection 0.2 } }
  texture { pigment { gradient y color_map { [0 rgbf <1, 1, 1, 1>] [0.5 rgbf <1, 0.8, 0.2, 0.3>] [1 rgbf <1, 1, 1, 1>] } } finish { ambient 0.1 diffuse 0.6 specular 0.4 reflection 0.1 } } }
