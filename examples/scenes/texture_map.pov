// checks: patterned textures (semantics §5.7): a checker of whole textures (one reflects, one has a highlight), a texture_map blending an opaque and a glass texture with ior, a hexagon whose entries are texture_maps themselves (nested), tiles/tile2, all turned and scaled with shadows
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 }
camera { location <0, 5, -9> look_at <0, 0.8, 0> right x*image_width/image_height angle 50 }
light_source { <-8, 15, -12> color rgb 1 }
light_source { <10, 8, -4> color rgb 0.5 }
plane { y, 0
  texture { checker
    texture { pigment { rgb <0.8, 0.75, 0.6> } finish { phong 0.8 phong_size 30 } }
    texture { pigment { rgb <0.1, 0.15, 0.3> } finish { reflection 0.4 ambient 0.05 } }
    scale 1.5 rotate 30*y } }
sphere { <-2.6, 1.2, 0>, 1.2
  texture { gradient y
    texture_map {
      [0.3 pigment { rgb <0.9, 0.2, 0.1> } finish { specular 0.6 roughness 0.02 }]
      [0.7 pigment { rgbf <0.9, 1, 0.9, 0.9> } finish { reflection 0.1 phong 1 }]
    }
    scale 2.4 translate -1.2*y translate <-2.6, 1.2, 0> }
  interior { ior 1.5 } }
box { <-1, 0, -1>, <1, 1.6, 1>
  texture { hexagon
    texture { pigment { rgb <0.2, 0.7, 0.3> } }
    texture { wood
      texture_map {
        [0.2 pigment { rgb <1, 0.9, 0.3> } finish { ambient 0.3 }]
        [0.8 pigment { rgb <0.4, 0.2, 0.1> } finish { phong 0.5 }]
      } scale 0.3 }
    texture { pigment { rgb <0.9, 0.9, 0.95> } finish { diffuse 0.9 reflection 0.2 } }
    rotate 90*x scale 0.35 rotate 25*y }
  rotate -20*y translate <0.6, 0, 0.8> }
sphere { <2.9, 1, -0.5>, 1
  texture {
    tiles { texture { pigment { rgb <0.3, 0.3, 0.9> } finish { phong 1 } }
      tile2 texture { pigment { rgb <0.95, 0.6, 0.2> } } }
    scale 0.5 rotate <20, 30, 0> } }
