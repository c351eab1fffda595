// checks: pigment_map (declared, nested, entries with their own patterns and transforms, the outer
// pigment's transform over them), a checker and a hexagon listing pigments, average (weights, a
// checker entry whose face the box's front face lies on)
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 1.5, -6> look_at <0, 0.5, 0> right x*image_width/image_height }
light_source { <-5, 8, -6> color rgb 1 }
background { rgb <0.2, 0.3, 0.5> }
#declare Bands = pigment_map {
  [0 rgb <1, 0, 0>]
  [0.5 checker rgb 1 rgb 0 scale 0.2]
  [1 gradient x color_map { [0 rgb <0, 0, 1>] [1 rgb <0, 1, 0>] } scale 0.3]
}
plane { y, -1
  pigment { checker pigment { rgb <1, 1, 0> } pigment { leopard color_map { [0 rgb 0] [1 rgb <1, 0.5, 0>] } scale 0.1 } }
}
sphere { <-1.5, 0.2, 0>, 1 pigment { gradient y pigment_map { Bands } scale 1.5 translate -y*0.5 } }
sphere { <1.5, 0.2, 0>, 1
  pigment {
    onion
    pigment_map {
      [0.2 rgb <0.9, 0.9, 0.9>]
      [0.4 radial frequency 8 color_map { [0 rgb <0.2, 0.3, 0.9>] [1 rgb 1] }]
      [0.8 spherical pigment_map { [0 rgb <0.5, 0, 0.5>] [1 rgb <0, 0.5, 0.2>] } scale 0.3]
    }
    scale 0.6 rotate y*30
  }
}
box { <-0.4, -1, 1.5>, <0.4, 1.2, 2.3>
  pigment { hexagon pigment { rgb <0.8, 0.1, 0.1> } pigment { boxed color_map { [0 rgb 0] [1 rgb 1] } scale 0.2 }
            pigment { rgb <0.1, 0.2, 0.8> } rotate x*90 scale 0.25 } }
box { <-3.4, -1, 1>, <-2.2, 0.5, 2>
  pigment { average pigment_map { [1 checker rgb 1 rgb 0 scale 0.25]
                                  [3 gradient x color_map { [0 rgb <1, 0, 0>] [1 rgb <0, 0, 1>] }]
                                  [2 rgb <0, 1, 0>] } } }
