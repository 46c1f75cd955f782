#include "client/render/shaders.h"

namespace vsurg::client::shaders {

// Both stages of the lit surfaces, after the variant's #defines: the uniforms, the tissue's
// albedo, the key, fill and sky light that does not depend on the view, and the specular lobes.
// Below high the tissue takes the diffuse light and its broad lobe per vertex (VERTEX_LIGHT):
// they vary over centimetres, which its vertices resolve, and on a software renderer every term
// moved out of the pixel is time saved on every pixel. What stays per pixel there is the key
// light's shadow and, on a wet surface, the film's sharp lobe (a highlight a few vertices wide).
const char* const kSceneCommon = R"(
uniform vec3 uEye;
uniform vec3 uKeyDir;         // unit, toward the key light
uniform vec3 uKeyColour;
uniform vec3 uFillDir;
uniform vec3 uFillColour;
uniform vec3 uUp;
uniform vec3 uSky;
uniform vec3 uGround;
uniform vec3 uAlbedo;
uniform float uRoughness;
#define TISSUE (MATERIAL == 0 || MATERIAL == 1 || MATERIAL == 2)
#define WET (MATERIAL == 1 || MATERIAL == 2)
#define POLISHED (MATERIAL == 3 || MATERIAL == 4)
#define VERTEX_LIGHT (TISSUE && !DETAIL && !AO && !ALBEDO_ONLY)

// d: r tone, g pores, b veins or vessels, a height.
vec3 Albedo(vec4 d) {
  vec3 albedo = uAlbedo;
#if MATERIAL == 0  // skin: tone, pores and faint veins
  albedo *= mix(0.80, 1.12, d.r);
  albedo *= 1.0 - 0.14 * d.g;
  albedo = mix(albedo, albedo * vec3(0.78, 0.80, 1.02), 0.55 * d.b);
#elif WET  // organ, kidney: mottling and vessels
  albedo *= mix(0.80, 1.12, d.r);
  vec3 vessel = MATERIAL == 2 ? vec3(0.22, 0.05, 0.08) : vec3(0.30, 0.06, 0.07);
  albedo = mix(albedo, vessel, 0.6 * d.b);
#elif MATERIAL == 5  // the drape's weave
  albedo *= mix(0.85, 1.05, d.r);
#endif
  return albedo;
}

// The diffuse light, split by the key light's shadow: always + shadow * lit (shadow 1 = lit).
void Diffuse(vec3 n, vec3 albedo, float ao, out vec3 always, out vec3 lit) {
  float NoL = dot(n, uKeyDir);
#if MATERIAL == 0
  // Skin: wrapped diffuse, red reaching furthest past the terminator, and in the shadow the
  // light still scattering in.
  vec3 w = vec3(0.55, 0.30, 0.22);
  vec3 wrapped = albedo * uKeyColour * clamp((vec3(NoL) + w) / ((1.0 + w) * (1.0 + w)), 0.0, 1.0);
  always = wrapped * vec3(0.55, 0.35, 0.3);
  lit = wrapped - always;
#elif MATERIAL == 3  // metal: no diffuse
  always = vec3(0.0);
  lit = vec3(0.0);
#else
  always = vec3(0.0);
  lit = albedo * uKeyColour * max(NoL, 0.0);
#endif
#if MATERIAL != 3
  always += albedo * uFillColour * max(dot(n, uFillDir), 0.0);
  always += albedo * mix(uGround, uSky, 0.5 + 0.5 * dot(n, uUp)) * ao;
#endif
}
const float PI = 3.14159265;
float DistributionGgx(float NoH, float a) {
  float a2 = a * a;
  float d = NoH * NoH * (a2 - 1.0) + 1.0;
  return a2 / (PI * d * d);
}
float VisibilitySmith(float NoV, float NoL, float a) {
  float a2 = a * a;
  float gv = NoL * sqrt(NoV * NoV * (1.0 - a2) + a2);
  float gl = NoV * sqrt(NoL * NoL * (1.0 - a2) + a2);
  return 0.5 / max(gv + gl, 1e-5);
}
vec3 FresnelSchlick(vec3 f0, float VoH) {
  float f = 1.0 - VoH;
  float f2 = f * f;
  return f0 + (1.0 - f0) * (f2 * f2 * f);
}
// The key light's lobes, times NoL: the surface's own (`broad`) and, on a wet surface, 0.9 × the
// film's sharp one (f0 0.02, roughness 0.12), sharing the half vector and the angles.
vec3 Specular(vec3 n, vec3 v, vec3 l, vec3 f0, float roughness, bool broad, bool film) {
  vec3 h = normalize(v + l);
  float NoL = max(dot(n, l), 0.0), NoV = max(dot(n, v), 1e-4);
  float NoH = max(dot(n, h), 0.0), VoH = max(dot(v, h), 0.0);
  vec3 spec = vec3(0.0);
  if (broad) {
    float a = max(roughness * roughness, 0.002);
    spec += DistributionGgx(NoH, a) * VisibilitySmith(NoV, NoL, a) * FresnelSchlick(f0, VoH);
  }
  if (film) {
    float a = 0.12 * 0.12;
    spec += 0.9 * DistributionGgx(NoH, a) * VisibilitySmith(NoV, NoL, a) *
            FresnelSchlick(vec3(0.02), VoH);
  }
  return spec * NoL;
}
)";

const char* const kSceneVertex = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec3 aRest;
layout(location = 3) in vec2 aBroad;  // the tissue's broad detail: tone, vessels
uniform mat4 uViewProj;
uniform mat4 uModel;
uniform mat3 uNormalMatrix;
uniform mat4 uLightViewProj;
out vec3 vWorld;
out vec3 vNormal;
out vec3 vRest;
out vec4 vLight;
out vec2 vBroad;
#if VERTEX_LIGHT
out vec3 vAlways;  // Diffuse(), per vertex
out vec3 vLit;
#endif
void main() {
  vec4 world = uModel * vec4(aPosition, 1.0);
  vBroad = aBroad;
  vWorld = world.xyz;
  vNormal = uNormalMatrix * aNormal;
  vRest = aRest;
  vLight = uLightViewProj * world;
  gl_Position = uViewProj * world;
#if VERTEX_LIGHT
  vec3 n = normalize(vNormal);
  if (dot(n, uEye - vWorld) < 0.0) n = -n;  // the inside of an open rim
  Diffuse(n, Albedo(vec4(aBroad.x, 0.0, aBroad.y, 0.5)), 1.0, vAlways, vLit);
  // The broad lobe: lit by the key light as the diffuse is, so it joins vLit under the shadow.
  vLit += Specular(n, normalize(uEye - vWorld), uKeyDir, vec3(0.028), uRoughness, true, false) *
          uKeyColour;
#endif
}
)";

// Compiled once per variant (mesh_view.cpp prepends the #defines and kSceneCommon): MATERIAL
// (shaders.h), SHADOW_TAPS (0, 1, 4), DETAIL, AO and ALBEDO_ONLY (0 or 1). A software renderer
// runs both sides of a branch under a mask, so what a variant does not need is compiled out, not
// branched over.
const char* const kSceneFragment = R"(
in vec3 vWorld;
in vec3 vNormal;
in vec3 vRest;
in vec4 vLight;
in vec2 vBroad;
#if VERTEX_LIGHT
in vec3 vAlways;
in vec3 vLit;
#endif
uniform sampler2DShadow uShadowMap;
uniform float uShadowTexel;   // 1 / shadow map size
uniform sampler3D uDetail;    // r: tone, g: pores, b: veins, a: height (tiling)
uniform float uDetailScale;   // texture repeats per metre of rest position
uniform float uBumpDepth;     // m, the height's amplitude
uniform float uTableHeight;   // m along uUp
uniform vec3 uFootCentre;     // the tissue's footprint on the table: an ellipse
uniform vec3 uFootA;
uniform vec3 uFootB;
out vec4 fragColour;

float Shadow() {
#if SHADOW_TAPS == 0
  return 1.0;
#else
  vec3 p = vLight.xyz / vLight.w * 0.5 + 0.5;
  float bias = 0.002;
#if SHADOW_TAPS == 1
  float s = texture(uShadowMap, vec3(p.xy, p.z - bias));
#else
  // Four bilinear comparisons a texel and a half apart: each is already a 2×2 filter, so the
  // edge is as soft as a 4×4 kernel's for a quarter of its fetches.
  float s = 0.0;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      s += texture(uShadowMap, vec3(p.xy + (vec2(i, j) - 0.5) * uShadowTexel * 1.5, p.z - bias));
  s *= 0.25;
#endif
  // Outside the light's box: lit.
  bool outside = p.z > 1.0 || p.x < 0.0 || p.y < 0.0 || p.x > 1.0 || p.y > 1.0;
  return outside ? 1.0 : s;
#endif
}
// What a polished surface reflects: the room's hemisphere and the theatre light's softbox.
// The floor, the theatre's pale walls at the horizon, the ceiling, and the theatre light's
// softbox overhead.
vec3 Environment(vec3 dir, float roughness) {
  float u = dot(dir, uUp);
  vec3 walls = vec3(0.62, 0.66, 0.70);
  vec3 c = mix(uGround * 3.0, walls, smoothstep(-0.35, 0.0, u));
  c = mix(c, uSky * 1.6, smoothstep(0.1, 0.6, u));
  float box = smoothstep(0.80 - roughness * 0.5, 0.95, u);
  return c + vec3(1.6) * box * (1.0 - roughness);
}
vec3 Tonemap(vec3 x) {  // Narkowicz's fit of ACES, then display gamma
  vec3 m = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
  return sqrt(m);  // display gamma 2.0: a square root is a fraction of pow's cost on a CPU
}

void main() {
#if MATERIAL == 6  // the table's shadows, blended over its picture
  fragColour = vec4(0.0, 0.0, 0.0, (1.0 - Shadow()) * 0.6);
#else
  vec3 n = normalize(vNormal);
  vec3 v = normalize(uEye - vWorld);
  if (dot(n, v) < 0.0) n = -n;  // the inside of an open rim
  vec4 d = vec4(0.5, 0.0, 0.0, 0.5);
#if TISSUE
  d.rb = vBroad;
#endif
#if DETAIL
  // Pores and the bump from the texture; tone and vessels (the same texture at an eighth of
  // the scale) sampled per vertex.
  vec4 fine = texture(uDetail, vRest * uDetailScale);
#if TISSUE
  d.ga = fine.ga;
#else
  d = fine;
#endif
#if !ALBEDO_ONLY
  // Bump by the surface gradient of the height (Mikkelsen 2010): no tangent frame needed.
  float h = (d.a - 0.5) * uBumpDepth;
  vec3 dpdx = dFdx(vWorld), dpdy = dFdy(vWorld);
  vec3 r1 = cross(dpdy, n), r2 = cross(n, dpdx);
  float det = dot(dpdx, r1);
  vec3 grad = sign(det) * (dFdx(h) * r1 + dFdy(h) * r2);
  vec3 bumped = abs(det) * n - grad;
  n = abs(det) > 1e-14 && dot(bumped, bumped) > 0.0 ? normalize(bumped) : n;
#endif
#endif
  float roughness = uRoughness;
  vec3 f0 = vec3(0.028);
#if MATERIAL == 3  // metal: the albedo is the reflectance
  f0 = uAlbedo;
#elif MATERIAL == 4
  f0 = vec3(0.04);
#endif
#if ALBEDO_ONLY
  fragColour = vec4(pow(clamp(Albedo(d), 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
#else
  // Ambient occlusion, cheap: tissue near the table and facing it is darker; the table is
  // darker under the tissue's footprint.
  float ao = 1.0;
#if AO && MATERIAL == 5
  vec3 r = vWorld - uFootCentre;
  float e = length(vec2(dot(r, uFootA) / dot(uFootA, uFootA), dot(r, uFootB) / dot(uFootB, uFootB)));
  ao = 1.0 - 0.6 * exp(-max(e - 0.85, 0.0) * 5.0);
#elif AO && TISSUE
  float height = dot(vWorld, uUp) - uTableHeight;
  ao = mix(0.45, 1.0, smoothstep(0.0, 0.03, height)) * (0.8 + 0.2 * dot(n, uUp));
#endif
  float shadow = Shadow();
#if VERTEX_LIGHT
  vec3 always = vAlways, lit = vLit;
#else
  vec3 always, lit;
  Diffuse(n, Albedo(d), ao, always, lit);
#endif
#if MATERIAL == 5 || (VERTEX_LIGHT && !WET)
  vec3 spec = vec3(0.0);  // cloth: no highlight worth its cost; skin below high: per vertex
#elif VERTEX_LIGHT  // a wet tissue below high: its broad lobe per vertex, the film's here
  vec3 spec = Specular(n, v, uKeyDir, f0, roughness, false, true) * uKeyColour * shadow;
#else
  vec3 spec = Specular(n, v, uKeyDir, f0, roughness, true, WET) * uKeyColour * shadow;
#endif
  vec3 colour = always + lit * shadow + spec;
#if POLISHED  // a polished surface reflects the room
  vec3 rv = reflect(-v, n);
  float NoV = max(dot(n, v), 0.0);
  colour += Environment(rv, roughness) * FresnelSchlick(f0, NoV) * ao * (1.0 - roughness * 0.5);
#endif
  fragColour = vec4(Tonemap(colour), 1.0);
#endif
#endif
}
)";

const char* const kShadowVertex = R"(#version 330 core
layout(location = 0) in vec3 aPosition;
uniform mat4 uLightViewProj;
uniform mat4 uModel;
void main() { gl_Position = uLightViewProj * uModel * vec4(aPosition, 1.0); }
)";

const char* const kShadowFragment = R"(#version 330 core
void main() {}
)";

const char* const kFlatVertex = R"(#version 330 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec4 aColour;
uniform mat4 uViewProj;
out vec4 vColour;
void main() {
  vColour = aColour;
  gl_Position = uViewProj * vec4(aPosition, 1.0);
}
)";

const char* const kFlatFragment = R"(#version 330 core
in vec4 vColour;
out vec4 fragColour;
void main() { fragColour = vColour; }
)";

}  // namespace vsurg::client::shaders
