// a seed for benchmarks/fuzz.py: the interpreter's directives in one small scene
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }
#include "colors.inc"
#declare N = 4;
#declare Names = array[3] { "red", "green", "blue" }
#declare Values = array[N];
#macro Ring(R, K)
  #local I = 0;
  union {
    #while (I < K)
      sphere { <R * cos(2 * pi * I / K), 0.3, R * sin(2 * pi * I / K)>, 0.2
               pigment { rgb <mod(I, 2), I / K, 0.5> } }
      #local I = I + 1;
    #end
  }
#end
#for (J, 0, N - 1)
  #declare Values[J] = pow(J, 2) + sqrt(J);
#end
#declare S = concat("n=", str(N, 0, 0), " ", Names[1], " ", chr(65), substr("abcdef", 2, 3));
#debug concat(S, "\n")
#fopen Out "fuzz_data.inc" write
#write (Out, "#declare Read = ", Values[2], ";\n")
#fclose Out
#include "fuzz_data.inc"
#declare F = function(x, y, z) { x * x + y * y - z }
#switch (N)
  #case (4) #declare Pick = F(1, 2, 3); #break
  #range (5, 9) #declare Pick = 0; #break
  #else #declare Pick = -1;
#end
#ifdef (Pick) #declare Size = vlength(<1, 2, 2>) / 3; #end
#ifndef (Undefined) #declare Size = Size * 1; #end
camera { location <0, 2, -5> look_at <0, 0.5, 0> angle 45 }
light_source { <-5, 8, -5> color White }
plane { y, 0 pigment { checker color Gray50, color White scale 0.5 } }
object { Ring(1.5, 8) }
difference {
  box { -Size, Size }
  cylinder { -2 * x, 2 * x, 0.5 }
  translate <0, Size, 0> rotate <0, 30 + Read + Pick, 0>
  pigment { rgbf <0.9, 0.9, 1, 0.8> } finish { reflection { 0.1 } } interior { ior 1.3 }
}
mesh2 {
  vertex_vectors { 4, <-1, 0, 2>, <1, 0, 2>, <1, 1, 2>, <-1, 1, 2> }
  face_indices { 2, <0, 1, 2>, <0, 2, 3> }
  pigment { color_map { [0 Red] [1 Blue] } gradient y }
}
torus { 0.6, 0.1 translate <0, 0.1, -1.5> pigment { rgb <1, 0.8, 0.2> } }
