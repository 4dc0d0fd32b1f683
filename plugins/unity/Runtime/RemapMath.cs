// RemapMath.cs -- the per-frame remap in float32: triangle frames, the local profile (affine and
// rigid laws) and the games profile of spec v1.2, with the float32 build of
// native/gsverse_remap.h's order of operations (everything relative to the triangle's first
// corner, added back last). Plain structs and static methods on them, no managed allocation:
// the loops of Remapper can be moved into Burst jobs (IJobParallelFor over faces, then over
// splats) with the arrays as NativeArrays.
using System;

namespace Gsverse.MeshAnchor
{
    public struct Float3
    {
        public float X, Y, Z;
        public Float3(float x, float y, float z) { X = x; Y = y; Z = z; }
        public static Float3 operator +(Float3 a, Float3 b) { return new Float3(a.X + b.X, a.Y + b.Y, a.Z + b.Z); }
        public static Float3 operator -(Float3 a, Float3 b) { return new Float3(a.X - b.X, a.Y - b.Y, a.Z - b.Z); }
        public static Float3 operator *(Float3 a, float s) { return new Float3(a.X * s, a.Y * s, a.Z * s); }
        public static Float3 operator *(float s, Float3 a) { return new Float3(s * a.X, s * a.Y, s * a.Z); }
        public static Float3 operator /(Float3 a, float s) { return new Float3(a.X / s, a.Y / s, a.Z / s); }
        public static float Dot(Float3 a, Float3 b) { return a.X * b.X + a.Y * b.Y + a.Z * b.Z; }
        public static Float3 Cross(Float3 a, Float3 b)
        {
            return new Float3(a.Y * b.Z - a.Z * b.Y, a.Z * b.X - a.X * b.Z, a.X * b.Y - a.Y * b.X);
        }
        public float this[int i] { get { return i == 0 ? X : i == 1 ? Y : Z; } }
        /// <summary>A copy with component i set to v.</summary>
        public Float3 With(int i, float v) { return new Float3(i == 0 ? v : X, i == 1 ? v : Y, i == 2 ? v : Z); }
        public static Float3 Abs(Float3 a) { return new Float3(Math.Abs(a.X), Math.Abs(a.Y), Math.Abs(a.Z)); }
    }

    /// <summary>A quaternion x, y, z, w.</summary>
    public struct Quat
    {
        public float X, Y, Z, W;
        public Quat(float x, float y, float z, float w) { X = x; Y = y; Z = z; W = w; }
    }

    /// <summary>A 3x3 matrix by its columns.</summary>
    public struct Mat3
    {
        public Float3 C0, C1, C2;
        public Mat3(Float3 c0, Float3 c1, Float3 c2) { C0 = c0; C1 = c1; C2 = c2; }
        public static Mat3 Identity { get { return new Mat3(new Float3(1, 0, 0), new Float3(0, 1, 0), new Float3(0, 0, 1)); } }
        public Float3 Row(int r) { return new Float3(C0[r], C1[r], C2[r]); }
        public static Float3 operator *(Mat3 m, Float3 v) { return m.C0 * v.X + m.C1 * v.Y + m.C2 * v.Z; }
        public static Mat3 operator *(Mat3 a, Mat3 b) { return new Mat3(a * b.C0, a * b.C1, a * b.C2); }
        public static Mat3 operator *(float s, Mat3 m) { return new Mat3(s * m.C0, s * m.C1, s * m.C2); }
        /// <summary>Column c.</summary>
        public Float3 this[int c]
        {
            get { return c == 0 ? C0 : c == 1 ? C1 : C2; }
            set { if (c == 0) C0 = value; else if (c == 1) C1 = value; else C2 = value; }
        }
        public Mat3 Transpose() { return new Mat3(Row(0), Row(1), Row(2)); }
        public float Determinant() { return Float3.Dot(C0, Float3.Cross(C1, C2)); }
    }

    /// <summary>Rest data of one face, local profile: computed in double by AnchoredAsset,
    /// stored as float (the layout of the kernels' rest buffer).</summary>
    public struct RestFace
    {
        public float Inv0, Inv1, Inv2, Inv3;   // C_r^-1 row-major (Inv2 = 0)
        public float Area2, InvSqrtArea2;      // a_r, 1 / sqrt(a_r)
        public bool Regular;                   // regular at rest
    }

    /// <summary>The current state of one face, local profile.</summary>
    public struct LocalFace
    {
        public Float3 O, E1, E2, M;   // first corner, edges, scaled normal
        public Mat3 AAff, R;          // [E_c C_r^-1 | m] (R_c if degenerate at rest), R_c
        public float K;               // sqrt(a_c / a_r) (1 if degenerate at rest)
    }

    /// <summary>The current state of one face, games profile: frame [n | b1 | b2], base scales.</summary>
    public struct GamesFace
    {
        public Float3 O, E1, E2;
        public Mat3 R;
        public Float3 Base;
    }

    public static class RemapMath
    {
        public const float EpsDegenerate = 1e-6f;   // regular iff a > eps * l^2 (spec Triangle frames)
        public const float GamesEps = 1e-8f;        // GaMeS absolute epsilon, scene units

        static float Sqrt(float x) { return (float)Math.Sqrt(x); }

        /// <summary>normalize(t x u), u the axis with the smallest |t_k| (lowest k on ties).</summary>
        public static Float3 Perp(Float3 t)
        {
            float ax = Math.Abs(t.X), ay = Math.Abs(t.Y), az = Math.Abs(t.Z);
            int k = 0;
            if (ay < ax) k = 1;
            if (az < (k == 0 ? ax : ay)) k = 2;
            var u = new Float3(k == 0 ? 1 : 0, k == 1 ? 1 : 0, k == 2 ? 1 : 0);
            Float3 o = Float3.Cross(t, u);
            return o * (1f / Sqrt(Float3.Dot(o, o)));
        }

        /// <summary>The local frame (spec Triangle frames): columns t, b, n; a = |e1 x e2|.</summary>
        public static Mat3 Frame(Float3 e1, Float3 e2, out float area2, out Float3 cr)
        {
            Float3 e3 = e2 - e1;
            cr = Float3.Cross(e1, e2);
            float a = Sqrt(Float3.Dot(cr, cr));
            float s1 = Float3.Dot(e1, e1), s2 = Float3.Dot(e2, e2), s3 = Float3.Dot(e3, e3);
            float longest2 = Math.Max(Math.Max(s1, s2), s3);
            area2 = a;
            if (a > EpsDegenerate * longest2)
            {
                Float3 t = e1 * (1f / Sqrt(s1)), n = cr * (1f / a);
                return new Mat3(t, Float3.Cross(n, t), n);
            }
            if (longest2 > 0)
            {
                // a segment: t along the longest of (e1, e2, e3) by squared length, first on ties
                Float3 d = e1;
                float best = s1;
                if (s2 > best) { d = e2; best = s2; }
                if (s3 > best) { d = e3; best = s3; }
                Float3 t = d * (1f / Sqrt(best)), n = Perp(t);
                return new Mat3(t, Float3.Cross(n, t), n);
            }
            return Mat3.Identity;
        }

        public static LocalFace Local(Float3 v0, Float3 v1, Float3 v2, RestFace rest)
        {
            var f = new LocalFace { O = v0, E1 = v1 - v0, E2 = v2 - v0 };
            float ac;
            Float3 cr;
            f.R = Frame(f.E1, f.E2, out ac, out cr);
            if (rest.Regular)
            {
                float rootC = Sqrt(ac);
                f.K = rootC * rest.InvSqrtArea2;
                f.M = rootC > 0 ? cr / rootC * rest.InvSqrtArea2 : new Float3(0, 0, 0);
                f.AAff = new Mat3(f.E1 * rest.Inv0 + f.E2 * rest.Inv2, f.E1 * rest.Inv1 + f.E2 * rest.Inv3, f.M);
            }
            else
            {
                // degenerate at rest: G := I, k := 1, m := n_c, A := R_c (both laws)
                f.K = 1;
                f.M = f.R.C2;
                f.AAff = f.R;
            }
            return f;
        }

        /// <summary>Rotation matrix of a quaternion (x, y, z, w), normalized first.</summary>
        public static Mat3 QuatToMatrix(float qx, float qy, float qz, float qw)
        {
            float len = Sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
            float x = 0, y = 0, z = 0, w = 1;
            if (len > 0) { x = qx / len; y = qy / len; z = qz / len; w = qw / len; }
            return new Mat3(new Float3(1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)),
                            new Float3(2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)),
                            new Float3(2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)));
        }

        /// <summary>M M^T as xx, xy, xz, yy, yz, zz into cov[6 i ..].</summary>
        public static void Outer(Mat3 m, float[] cov, int i)
        {
            Float3 r0 = m.Row(0), r1 = m.Row(1), r2 = m.Row(2);
            cov[6 * i] = Float3.Dot(r0, r0); cov[6 * i + 1] = Float3.Dot(r0, r1);
            cov[6 * i + 2] = Float3.Dot(r0, r2); cov[6 * i + 3] = Float3.Dot(r1, r1);
            cov[6 * i + 4] = Float3.Dot(r1, r2); cov[6 * i + 5] = Float3.Dot(r2, r2);
        }

        // ---- rotation + scale outputs (the covariance is normative)

        public const int JacobiSweeps = 6;   // cyclic sweeps, converged for 3x3 (plugins/web/src/decompose.js)

        /// <summary>Quaternion (x, y, z, w; w >= 0) of a rotation matrix: Shepperd, pivot on
        /// the largest of 4x^2, 4y^2, 4z^2, 4w^2.</summary>
        public static Quat MatToQuat(Mat3 m)
        {
            float m00 = m.C0.X, m11 = m.C1.Y, m22 = m.C2.Z;
            float m01 = m.C1.X, m02 = m.C2.X, m10 = m.C0.Y, m12 = m.C2.Y, m20 = m.C0.Z, m21 = m.C1.Z;
            float tr = m00 + m11 + m22;
            float c0 = 1 + 2 * m00 - tr, c1 = 1 + 2 * m11 - tr, c2 = 1 + 2 * m22 - tr, c3 = 1 + tr;
            int k = 0;
            float best = c0;
            if (c1 > best) { k = 1; best = c1; }
            if (c2 > best) { k = 2; best = c2; }
            if (c3 > best) { k = 3; best = c3; }
            float s = 2 * Sqrt(Math.Max(best, 0f));
            if (!(s > 0)) return new Quat(0, 0, 0, 1);
            Quat q;
            if (k == 3) q = new Quat((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, s / 4);
            else if (k == 0) q = new Quat(s / 4, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s);
            else if (k == 1) q = new Quat((m01 + m10) / s, s / 4, (m12 + m21) / s, (m02 - m20) / s);
            else q = new Quat((m02 + m20) / s, (m12 + m21) / s, s / 4, (m10 - m01) / s);
            float len = Sqrt(q.X * q.X + q.Y * q.Y + q.Z * q.Z + q.W * q.W);
            if (q.W < 0) len = -len;
            return new Quat(q.X / len, q.Y / len, q.Z / len, q.W / len);
        }

        /// <summary>One Jacobi rotation zeroing a(p, q) of a symmetric a; v accumulates the
        /// eigenvectors (columns). t = sign(theta) / (|theta| + sqrt(theta^2 + 1)): |t| <= 1.</summary>
        static void JacobiRotate(ref Mat3 a, ref Mat3 v, int p, int q)
        {
            float apq = a[q][p];
            if (apq == 0) return;
            float theta = (a[q][q] - a[p][p]) / (2 * apq);
            float t = (theta >= 0 ? 1f : -1f) / (Math.Abs(theta) + Sqrt(theta * theta + 1));
            float c = 1 / Sqrt(t * t + 1), s = t * c;
            // A <- J^T A J: the column update A J, then the same update of the transpose
            Float3 cp = a[p], cq = a[q];
            a[p] = c * cp - s * cq;
            a[q] = s * cp + c * cq;
            a = a.Transpose();
            cp = a[p]; cq = a[q];
            a[p] = c * cp - s * cq;
            a[q] = s * cp + c * cq;
            a[q] = a[q].With(p, 0);   // annihilated exactly
            a[p] = a[p].With(q, 0);
            cp = v[p]; cq = v[q];     // V <- V J
            v[p] = c * cp - s * cq;
            v[q] = s * cp + c * cq;
        }

        /// <summary>Sigma = R diag(scale)^2 R^T by cyclic Jacobi on Sigma / max|Sigma_ij|; R
        /// right-handed; scales sqrt(max(lambda, 0)). The kernels' and the web plugin's algorithm.</summary>
        public static void CovToRotScale(Mat3 sigma, out Quat quat, out Float3 scale)
        {
            Float3 m0 = Float3.Abs(sigma.C0), m1 = Float3.Abs(sigma.C1), m2 = Float3.Abs(sigma.C2);
            float norm = Math.Max(Math.Max(Math.Max(m0.X, m0.Y), Math.Max(m0.Z, m1.Y)), Math.Max(m1.Z, m2.Z));
            if (!(norm > 0))
            {
                quat = new Quat(0, 0, 0, 1);
                scale = new Float3(0, 0, 0);
                return;
            }
            Mat3 a = (1 / norm) * sigma, v = Mat3.Identity;
            for (int sweep = 0; sweep < JacobiSweeps; ++sweep)
            {
                JacobiRotate(ref a, ref v, 0, 1);
                JacobiRotate(ref a, ref v, 0, 2);
                JacobiRotate(ref a, ref v, 1, 2);
            }
            if (v.Determinant() < 0) v.C2 = -1f * v.C2;
            quat = MatToQuat(v);
            scale = new Float3(Sqrt(Math.Max(a.C0.X * norm, 0f)), Sqrt(Math.Max(a.C1.Y * norm, 0f)),
                               Sqrt(Math.Max(a.C2.Z * norm, 0f)));
        }

        /// <summary>The games frame [n | b1 | b2] and base scales (spec Remap: the games
        /// profile), relative to v0: g = (e1 + e2) / 3, u = e1 - g, w = e2 - g.</summary>
        public static GamesFace Games(Float3 v0, Float3 v1, Float3 v2)
        {
            var f = new GamesFace { O = v0, E1 = v1 - v0, E2 = v2 - v0 };
            Float3 e1 = f.E1, e2 = f.E2;
            Float3 g = (e1 + e2) / 3f;
            Float3 u = e1 - g, w = e2 - g, e3 = e2 - e1;
            Float3 cr = Float3.Cross(e1, e2);
            float a = Sqrt(Float3.Dot(cr, cr));
            float s1 = Float3.Dot(e1, e1), s2 = Float3.Dot(e2, e2), s3 = Float3.Dot(e3, e3);
            float longest2 = Math.Max(Math.Max(s1, s2), s3);
            float tol = EpsDegenerate * Sqrt(longest2);   // relative tests on degenerate triangles
            float lu = Sqrt(Float3.Dot(u, u));
            Float3 n = new Float3(0, 0, 1), b1 = new Float3(1, 0, 0), b2 = new Float3(0, 1, 0);
            if (a > EpsDegenerate * longest2)
            {
                b1 = u * (1f / lu);
                n = cr * (1f / a);
                b2 = Float3.Cross(n, b1);
            }
            else if (lu > tol)
            {
                // degenerate: b2 from w by Gram-Schmidt against b1
                b1 = u * (1f / lu);
                Float3 rr = w - Float3.Dot(w, b1) * b1;
                float lr = Sqrt(Float3.Dot(rr, rr));
                b2 = lr > tol ? rr * (1f / lr) : Perp(b1);
                n = Float3.Cross(b1, b2);
            }
            else if (longest2 > 0)
            {
                // degenerate, v1 at the centroid: the splat lies along w
                b2 = w * (1f / Sqrt(Float3.Dot(w, w)));
                b1 = Perp(b2);
                n = Float3.Cross(b1, b2);
            }
            f.R = new Mat3(n, b1, b2);
            f.Base = new Float3(GamesEps, (lu + GamesEps) / 2, Float3.Dot(w, b2) / 2);
            return f;
        }
    }
}
