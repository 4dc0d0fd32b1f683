// Remapper.cs -- the per-frame remap of one AnchoredAsset on the CPU in float32: per face, then
// per splat (the two loops are independent iterations, the shape of two Burst
// IJobParallelFor jobs). Every array is allocated once, in the constructor: Apply allocates
// nothing.
using System;

namespace Gsverse.MeshAnchor
{
    public sealed class Remapper
    {
        readonly AnchoredAsset asset;
        readonly LocalFace[] local;
        readonly GamesFace[] games;
        /// <summary>Outputs of the last Apply: means (3N) and covariances (6N: xx, xy, xz, yy, yz, zz).</summary>
        public readonly float[] Means, Cov;
        /// <summary>With rotationScale: rotations (4N: x, y, z, w; w >= 0) and scales (3N), for
        /// renderers that store splats that way (rigid and games directly, affine by a Jacobi
        /// eigen-decomposition of the covariance, which is normative); else null.</summary>
        public readonly float[] Rotations, Scales;

        public Remapper(AnchoredAsset asset, bool rotationScale = false)
        {
            this.asset = asset;
            if (asset.Games) games = new GamesFace[asset.FaceCount];
            else local = new LocalFace[asset.FaceCount];
            Means = new float[3 * asset.Count];
            Cov = new float[6 * asset.Count];
            if (rotationScale)
            {
                Rotations = new float[4 * asset.Count];
                Scales = new float[3 * asset.Count];
            }
        }

        void Store(int i, Quat q, Float3 s)
        {
            Rotations[4 * i] = q.X; Rotations[4 * i + 1] = q.Y; Rotations[4 * i + 2] = q.Z; Rotations[4 * i + 3] = q.W;
            Scales[3 * i] = s.X; Scales[3 * i + 1] = s.Y; Scales[3 * i + 2] = s.Z;
        }

        static Float3 Vertex(float[] v, uint i) { return new Float3(v[3 * i], v[3 * i + 1], v[3 * i + 2]); }

        /// <summary>Remap every splat onto the current anchor vertices (3V floats, splat-local
        /// space, the order of the asset's anchor mesh).</summary>
        public void Apply(float[] vertices)
        {
            if (vertices.Length != asset.AnchorVertices.Length)
                throw new ArgumentException("expected " + asset.AnchorVertices.Length / 3 + " anchor vertices");
            uint[] idx = asset.Indices;
            for (int f = 0; f < asset.FaceCount; ++f)
            {
                Float3 v0 = Vertex(vertices, idx[3 * f]), v1 = Vertex(vertices, idx[3 * f + 1]), v2 = Vertex(vertices, idx[3 * f + 2]);
                if (asset.Games) games[f] = RemapMath.Games(v0, v1, v2);
                else local[f] = RemapMath.Local(v0, v1, v2, asset.Rest[f]);
            }
            for (int i = 0; i < asset.Count; ++i)
            {
                if (asset.Games) GamesSplat(i);
                else LocalSplat(i);
            }
        }

        void LocalSplat(int i)
        {
            LocalFace f = local[asset.Face[i]];
            float b1 = asset.Bary[2 * i], b2 = asset.Bary[2 * i + 1], d = asset.Offset[i];
            // mean = v0 + b1 e1 + b2 e2 + d m: the small part first, the corner last
            Float3 mean = f.O + (b1 * f.E1 + b2 * f.E2 + d * f.M);
            Means[3 * i] = mean.X; Means[3 * i + 1] = mean.Y; Means[3 * i + 2] = mean.Z;
            float[] q = asset.Rotation, s = asset.Scale;
            Mat3 rl = RemapMath.QuatToMatrix(q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]);
            var l = new Mat3(rl.C0 * s[3 * i], rl.C1 * s[3 * i + 1], rl.C2 * s[3 * i + 2]);   // R_l S_l
            Mat3 a = asset.Rigid ? f.K * f.R : f.AAff;                                     // A
            Mat3 m = a * l;
            RemapMath.Outer(m, Cov, i);                                                    // Sigma = (A L)(A L)^T
            if (Rotations == null) return;
            if (asset.Rigid)                                                               // R_c R_l, k s_l
                Store(i, RemapMath.MatToQuat(f.R * rl), new Float3(f.K * s[3 * i], f.K * s[3 * i + 1], f.K * s[3 * i + 2]));
            else
            {
                Quat quat;
                Float3 sc;
                RemapMath.CovToRotScale(m * m.Transpose(), out quat, out sc);
                Store(i, quat, sc);
            }
        }

        void GamesSplat(int i)
        {
            GamesFace f = games[asset.Face[i]];
            float a1 = asset.Bary[2 * i], a2 = asset.Bary[2 * i + 1], rho = asset.Offset[i];
            Float3 mean = f.O + (a1 * f.E1 + a2 * f.E2);
            Means[3 * i] = mean.X; Means[3 * i + 1] = mean.Y; Means[3 * i + 2] = mean.Z;
            // scale_j = max(rho s_j, 0) + eps
            float s0 = Math.Max(rho * f.Base.X, 0f) + RemapMath.GamesEps;
            float s1 = Math.Max(rho * f.Base.Y, 0f) + RemapMath.GamesEps;
            float s2 = Math.Max(rho * f.Base.Z, 0f) + RemapMath.GamesEps;
            RemapMath.Outer(new Mat3(f.R.C0 * s0, f.R.C1 * s1, f.R.C2 * s2), Cov, i);
            if (Rotations != null) Store(i, RemapMath.MatToQuat(f.R), new Float3(s0, s1, s2));
        }

        /// <summary>The rest covariance of every splat from the rest ROTATION (normalized) and
        /// SCALE, in double (6N floats).</summary>
        public static float[] RestCovariances(AnchoredAsset asset)
        {
            var cov = new float[6 * asset.Count];
            float[] q = asset.RestRotation, s = asset.RestScale;
            for (int i = 0; i < asset.Count; ++i)
            {
                double x = q[4 * i], y = q[4 * i + 1], z = q[4 * i + 2], w = q[4 * i + 3];
                double len = Math.Sqrt(x * x + y * y + z * z + w * w);
                if (len > 0) { x /= len; y /= len; z /= len; w /= len; } else { x = y = z = 0; w = 1; }
                double[] r = { 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                               2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                               2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y) };
                double[] m = new double[9];
                for (int rr = 0; rr < 3; ++rr) for (int c = 0; c < 3; ++c) m[3 * rr + c] = r[3 * rr + c] * s[3 * i + c];
                int[,] rs = { { 0, 0 }, { 0, 1 }, { 0, 2 }, { 1, 1 }, { 1, 2 }, { 2, 2 } };
                for (int j = 0; j < 6; ++j)
                {
                    int a = 3 * rs[j, 0], b = 3 * rs[j, 1];
                    cov[6 * i + j] = (float)(m[a] * m[b] + m[a + 1] * m[b + 1] + m[a + 2] * m[b + 2]);
                }
            }
            return cov;
        }
    }
}
