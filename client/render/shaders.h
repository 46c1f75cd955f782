// The station's GLSL 330 core shaders (client/render/shaders.cpp), one string per stage.
//
// Shading (docs/ARCHITECTURE.md "The station's view"): a metallic-roughness model (GGX
// distribution, height-correlated Smith visibility, Schlick Fresnel; Karis 2013, Burley 2012)
// lit by a key light that casts the shadow map, a fill light and a sky/ground hemisphere whose
// colours also stand in for the environment a metal reflects. Skin adds a cheap subsurface term:
// wrapped diffuse, wider in red than in blue (the pre-integrated skin idea of Penner 2011 in its
// simplest form), so a terminator reads soft and warm instead of a plastic edge. Organs add a
// second, sharp specular lobe: the wet film. Detail (tone, pores, veins, bump) comes from a
// tiling 3D noise texture sampled at the tissue's rest position, so it moves with the tissue;
// bump mapping by the surface gradient of that height (Mikkelsen 2010), no tangents needed.
#pragma once

namespace vsurg::client::shaders {

// The lit surfaces (tissue, table, instrument), each stage without its #version line: compiled
// per variant with MATERIAL, SHADOW_TAPS, DETAIL, AO and ALBEDO_ONLY defined (mesh_view.cpp),
// then kSceneCommon (what both stages use), then the stage.
extern const char* const kSceneCommon;
extern const char* const kSceneVertex;  // position, normal, rest position, broad detail
extern const char* const kSceneFragment;
extern const char* const kShadowVertex;    // depth only, from the key light
extern const char* const kShadowFragment;  // empty: depth is written by the fixed stage
extern const char* const kFlatVertex;      // guidance marks: position and colour, unlit
extern const char* const kFlatFragment;

// MATERIAL values.
inline constexpr int kSkin = 0, kOrgan = 1, kKidney = 2, kMetal = 3, kPlastic = 4, kDrape = 5;
// The table's shadows only: black, as opaque as the shadow is deep (blended).
inline constexpr int kShadowCatcher = 6;

}  // namespace vsurg::client::shaders
