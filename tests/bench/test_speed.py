"""``navbench bench`` names the CPU its figures were measured on."""

from navbench.bench.speed import cpu_description, format_report

AVX2_EPYC = """processor\t: 0
vendor_id\t: AuthenticAMD
cpu family\t: 25
model name\t: AMD EPYC
flags\t\t: fpu sse4_2 avx f16c avx2 fma

processor\t: 1
cpu family\t: 25
model name\t: AMD EPYC
flags\t\t: fpu sse4_2 avx f16c avx2 fma
"""


def test_cpu_description_names_model_family_and_widest_vector_extension():
    assert cpu_description(AVX2_EPYC) == "AMD EPYC, family 25, AVX2"
    bf16 = AVX2_EPYC.replace("avx2 fma", "avx2 fma avx512f avx512_bf16")
    assert cpu_description(bf16) == "AMD EPYC, family 25, AVX-512 with BF16"
    assert cpu_description(AVX2_EPYC.replace(" avx2", "").replace(" avx ", " ")) == "AMD EPYC, family 25, SSE4.2"
    assert cpu_description("") == "unknown, no AVX"


def test_the_report_prints_the_cpu():
    report = format_report({"scene": "s.glb", "scene_triangles": 3, "grid_shape": "2x2", "cpu": "AMD EPYC, AVX2",
                            "policy_steps_per_s_b1": 80.0})
    assert "cpu: AMD EPYC, AVX2" in report.splitlines()
    assert any(line.startswith("policy steps/s, batch 1") for line in report.splitlines())
