// Light sampling with multiple importance sampling (`phr_render::lights` and
// `PathTracer::advance_with_lights`): at every diffuse or fuzzy-metal hit one emitter (a
// triangle by area, a sphere by its cone, or the sky by a cosine-weighted direction) is
// sampled and its shadow ray traced at once (the CPU traces it later, which draws no random
// number); the power heuristic weighs it against the path's own bounce; Russian roulette after
// RR_START segments. Random numbers are drawn in the CPU's order.

fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let a = pdf * pdf;
    let b = other * other;
    if a + b > 0.0 && a + b < F32_MAX {
        return a / (a + b);
    }
    if pdf > F32_MAX {
        return 1.0;
    }
    return 0.0;
}

fn sky_probability() -> f32 {
    return frame.sky_probability;
}

fn light_count() -> u32 {
    return frame.light_count;
}

// `Material::has_lobe`: diffuse, or metal with fuzz.
fn has_lobe(m: Material) -> bool {
    let kind = m.kind;
    return kind == LAMBERTIAN || (kind == METAL && m.b.x > 0.0);
}

// `Material::lobe_pdf`: the density with which `scatter` leaves in the unit direction `out`.
fn lobe_pdf(m: Material, dir: vec3<f32>, normal: vec3<f32>, front: bool, out: vec3<f32>) -> f32 {
    let facing = select(-normal, normal, front);
    let cos_out = dot(facing, out);
    if cos_out <= 0.0 {
        return 0.0;
    }
    let kind = m.kind;
    if kind == LAMBERTIAN {
        return cos_out * FRAC_1_PI;
    }
    if kind != METAL || m.b.x <= 0.0 {
        return 0.0;
    }
    let r = unit(reflect(unit(dir), facing));
    let f = min(m.b.x, 1.0);
    let b = dot(out, r);
    let c = cross(out, r);
    let disc = f * f - dot(c, c);
    if disc <= 0.0 {
        return 0.0;
    }
    let sq = sqrt(disc);
    let far = b + sq;
    let near = max(b - sq, 0.0);
    if far <= 0.0 {
        return 0.0;
    }
    let four_pi = 2.0 * TAU;
    if m.b.y != 0.0 {
        return (far * far * far - near * near * near) / (four_pi * f * f * f);
    }
    return (far * far + near * near) / (four_pi * f * sq);
}

fn pdf_sky(facing: vec3<f32>, dir: vec3<f32>) -> f32 {
    if frame.background == ENVIRONMENT {
        // `sample_sky` returns no direction below the surface.
        if dot(facing, dir) > 0.0 {
            return sky_probability() * env_pdf(dir);
        }
        return 0.0;
    }
    return sky_probability() * max(dot(facing, dir), 0.0) * FRAC_1_PI;
}

// `1 − cos θmax` of the cone a sphere subtends seen from `seen_from` (0: from inside it or on it).
fn cone(center: vec3<f32>, radius: f32, seen_from: vec3<f32>) -> f32 {
    let r = abs(radius);
    let d = center - seen_from;
    let sin2 = r * r / dot(d, d);
    if !(sin2 < 1.0) {
        return 0.0;
    }
    return max(sin2 / (1.0 + sqrt(1.0 - sin2)), 0.0);
}

// `LightSet::pdf_hit`: the density with which light sampling seen_from `seen_from` picks the direction
// towards `point` on emitter `emitter` (its number plus one; 0: not a light).
fn pdf_hit(emitter: u32, seen_from: vec3<f32>, point: vec3<f32>, normal: vec3<f32>) -> f32 {
    if emitter == 0u || light_count() == 0u {
        return 0.0;
    }
    let light = lights[emitter - 1u];
    let selection = light.selection;
    if (light.material & SPHERE) == 0u {
        let to_light = point - seen_from;
        let dist2 = dot(to_light, to_light);
        let cos_light = abs(dot(normal, to_light)) / sqrt(dist2);
        let pdf = selection / light.area * dist2 / cos_light;
        return select(0.0, pdf, pdf < F32_MAX);
    }
    let one_minus_cos_max = cone(light.a, light.b.x, seen_from);
    if one_minus_cos_max <= 0.0 {
        return 0.0;
    }
    return selection / (TAU * one_minus_cos_max);
}

struct LightSample {
    dir: vec3<f32>,
    point: vec3<f32>,
    // The sample ends at `point` (false: the sky, at infinity).
    finite: bool,
    radiance: vec3<f32>,
    // 0: no sample.
    pdf: f32,
}

const NO_LIGHT: LightSample = LightSample(vec3<f32>(0.0), vec3<f32>(0.0), false, vec3<f32>(0.0), 0.0);

fn sample_sky(facing: vec3<f32>, rng: ptr<function, Pcg>) -> LightSample {
    if frame.background == ENVIRONMENT {
        let u1 = next_f32(rng);
        let u2 = next_f32(rng);
        let sample = env_sample(u1, u2);
        // Below the surface it lights nothing.
        if !(sample.w > 0.0) || dot(facing, sample.xyz) <= 0.0 {
            return NO_LIGHT;
        }
        return LightSample(sample.xyz, vec3<f32>(0.0), false, env_radiance(sample.xyz), sky_probability() * sample.w);
    }
    let d = facing + unit_vector(rng);
    let len = length(d);
    if !(len > 1.0e-6) {
        return NO_LIGHT;
    }
    let dir = d / len;
    let pdf = pdf_sky(facing, dir);
    if !(pdf > 0.0) {
        return NO_LIGHT;
    }
    return LightSample(dir, vec3<f32>(0.0), false, sky(dir), pdf);
}

// Duff et al. 2017 (glam's `any_orthonormal_pair`).
fn orthonormal_pair(n: vec3<f32>) -> array<vec3<f32>, 2> {
    // glam's `signum`: −1 for −0 too.
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) & 0x80000000u) != 0u);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return array<vec3<f32>, 2>(
        vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3<f32>(b, sign + n.y * n.y * a, -n.y),
    );
}

// `LightSet::sample`: a light and a direction towards it seen_from `position` (unit normal
// `facing` on the path's side).
fn sample_lights(position: vec3<f32>, facing: vec3<f32>, rng: ptr<function, Pcg>) -> LightSample {
    let pick = next_f32(rng);
    let sky_p = sky_probability();
    if pick < sky_p {
        return sample_sky(facing, rng);
    }
    let n = light_count();
    if n == 0u {
        return NO_LIGHT;
    }
    let total = light_cdf[n - 1u];
    let x = (pick - sky_p) / (1.0 - sky_p) * total;
    // The first weight above x (`partition_point(|c| c <= x)`), at most the last.
    var lo = 0u;
    var hi = n;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if light_cdf[mid] <= x {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let light = lights[min(lo, n - 1u)];
    let selection = light.selection;
    if !(selection > 0.0) {
        return NO_LIGHT;
    }
    let u1 = next_f32(rng);
    let u2 = next_f32(rng);
    let material = materials[light.material & ~SPHERE];
    var sample: LightSample;
    if (light.material & SPHERE) == 0u {
        let v0 = light.a;
        let e1 = light.b;
        let e2 = light.c;
        let s = sqrt(u1);
        let point = v0 + e1 * (s * (1.0 - u2)) + e2 * (s * u2);
        let to_light = point - position;
        let dist2 = dot(to_light, to_light);
        let dir = to_light / sqrt(dist2);
        let cos_light = -dot(unit(cross(e1, e2)), dir);
        let pdf = selection / light.area * dist2 / abs(cos_light);
        sample = LightSample(dir, point, true, emitted(material, cos_light > 0.0), pdf);
    } else {
        let center = light.a;
        let radius = light.b.x;
        let one_minus_cos_max = cone(center, radius, position);
        if one_minus_cos_max <= 0.0 {
            return NO_LIGHT;
        }
        let one_minus_cos = u1 * one_minus_cos_max;
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0));
        let to_center = center - position;
        let dist = length(to_center);
        let axis = to_center / dist;
        let basis = orthonormal_pair(axis);
        let phi = TAU * u2;
        let dir = unit(basis[0] * (sin_t * cos(phi)) + basis[1] * (sin_t * sin(phi)) + axis * cos_t);
        let r = abs(radius);
        let t = dist * cos_t - sqrt(max(r * r - dist * dist * sin_t * sin_t, 0.0));
        let point = position + dir * t;
        let front = dot(dir, (point - center) / radius) < 0.0;
        sample = LightSample(dir, point, true, emitted(material, front), selection / (TAU * one_minus_cos_max));
    }
    let d = abs(sample.dir);
    if !(sample.pdf > 0.0 && sample.pdf < F32_MAX && max(max(d.x, d.y), d.z) < F32_MAX) {
        return NO_LIGHT;
    }
    return sample;
}

fn trace_with_lights(camera_ray: Ray, rng: ptr<function, Pcg>) -> PathSample {
    var ray = camera_ray;
    var radiance = vec3<f32>(0.0);
    var throughput = vec3<f32>(1.0);
    var rays = 0u;
    // The previous vertex, if it sampled the lights: its position, facing normal and the
    // density of the direction the path took.
    var lit = false;
    var lit_position = vec3<f32>(0.0);
    var lit_facing = vec3<f32>(0.0);
    var lit_pdf = 0.0;
    var segment = 0u;
    loop {
        if segment >= frame.max_depth {
            break;
        }
        rays++;
        let hit = closest_hit(ray);
        if hit.slot == NO_HIT {
            let dir = unit(ray.dir);
            var weight = 1.0;
            if lit {
                weight = power_heuristic(lit_pdf, pdf_sky(lit_facing, dir));
            }
            radiance += throughput * sky(dir) * weight;
            break;
        }
        let surface = surface_at(ray, hit);
        let m = materials[surface.material];
        let light = emitted(m, surface.front);
        if any(light != vec3<f32>(0.0)) {
            var weight = 1.0;
            if lit {
                weight = power_heuristic(lit_pdf, pdf_hit(surface.emitter, lit_position, surface.position, surface.normal));
            }
            radiance += throughput * light * weight;
        }
        if segment + 1u >= frame.max_depth {
            break;
        }
        let facing = select(-surface.normal, surface.normal, surface.front);
        let lobe = has_lobe(m);
        // The lobe's scatter weight: the albedo, textured.
        let albedo = textured(m, surface, m.a);
        if lobe {
            let sample = sample_lights(surface.position, facing, rng);
            if sample.pdf > 0.0 {
                let pdf = lobe_pdf(m, ray.dir, surface.normal, surface.front, sample.dir);
                if pdf > 0.0 && any(sample.radiance != vec3<f32>(0.0)) {
                    rays++;
                    let origin = spawn_origin(surface, sample.dir);
                    var shadow: Ray;
                    if sample.finite {
                        shadow = make_ray(origin, sample.point - origin, 0.0, 1.0 - 1.0e-4);
                    } else {
                        shadow = make_ray(origin, sample.dir, 0.0, F32_MAX);
                    }
                    let weight = power_heuristic(sample.pdf, pdf);
                    if !any_hit(shadow) {
                        radiance += throughput * albedo * sample.radiance * (pdf * weight / sample.pdf);
                    }
                }
            }
        }
        let s = scatter(m, ray.dir, surface.normal, surface.front, rng);
        if s.weight.w == 0.0 {
            break;
        }
        if lobe {
            throughput *= albedo;
            lit = true;
            lit_position = surface.position;
            lit_facing = facing;
            lit_pdf = lobe_pdf(m, ray.dir, surface.normal, surface.front, unit(s.dir));
        } else {
            throughput *= s.weight.xyz;
            lit = false;
        }
        ray = make_ray(spawn_origin(surface, s.dir), s.dir, 0.0, F32_MAX);
        segment++;
        if segment >= RR_START {
            let survive = min(max(max(throughput.x, throughput.y), throughput.z), 1.0);
            if next_f32(rng) >= survive {
                break;
            }
            throughput /= survive;
        }
    }
    return PathSample(radiance, rays);
}
