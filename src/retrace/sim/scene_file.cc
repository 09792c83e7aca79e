#include "retrace/sim/scene_file.h"

#include <map>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <opencv2/imgcodecs.hpp>

#include "retrace/util/error.h"

namespace retrace {
namespace {

void AddNode(const aiScene* ai, const aiNode* node, const aiMatrix4x4& parent, const std::vector<int>& materials,
             const std::vector<bool>& textured, const Eigen::Matrix3f& to_town, float scale, Mesh* mesh) {
  const aiMatrix4x4 transform = parent * node->mTransformation;
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    const aiMesh* am = ai->mMeshes[node->mMeshes[m]];
    const bool has_uv = am->HasTextureCoords(0) && textured[am->mMaterialIndex];
    auto vertex = [&](unsigned i) {
      const aiVector3D p = transform * am->mVertices[i];
      return Vector3f(to_town * Vector3f(p.x, p.y, p.z) * scale);
    };
    auto uv = [&](unsigned i) {
      // Image rows grow downwards, texture v of most formats upwards.
      return has_uv ? Vector2f(am->mTextureCoords[0][i].x, 1.0f - am->mTextureCoords[0][i].y) : Vector2f(0, 0);
    };
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices != 3) continue;
      const unsigned a = face.mIndices[0], b = face.mIndices[1], c = face.mIndices[2];
      mesh->AddTriangle(vertex(a), vertex(b), vertex(c), uv(a), uv(b), uv(c), materials[am->mMaterialIndex]);
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c) {
    AddNode(ai, node->mChildren[c], transform, materials, textured, to_town, scale, mesh);
  }
}

}  // namespace

void LoadSceneFile(const std::filesystem::path& path, const SceneFileOptions& options, Scene* scene) {
  Assimp::Importer importer;
  const aiScene* ai = importer.ReadFile(
      path.string(), aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_SortByPType |
                         aiProcess_FindDegenerates | aiProcess_ValidateDataStructure);
  if (!ai || !ai->mRootNode || (ai->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
    throw InputError(path.string(), std::string("cannot read the scene file: ") + importer.GetErrorString());
  }
  std::vector<int> materials(ai->mNumMaterials);
  std::vector<bool> textured(ai->mNumMaterials, false);
  std::map<std::string, int> textures;
  for (unsigned i = 0; i < ai->mNumMaterials; ++i) {
    const aiMaterial* am = ai->mMaterials[i];
    Material material;
    aiColor4D diffuse;
    if (aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &diffuse) == AI_SUCCESS) {
      material.color = Vector3f(diffuse.r, diffuse.g, diffuse.b);
    }
    aiString file;
    if (am->GetTexture(aiTextureType_DIFFUSE, 0, &file) == AI_SUCCESS && file.length > 0 && file.C_Str()[0] != '*') {
      const std::filesystem::path texture_path = path.parent_path() / file.C_Str();
      auto it = textures.find(texture_path.string());
      if (it == textures.end()) {
        const cv::Mat image = cv::imread(texture_path.string(), cv::IMREAD_COLOR);
        CheckInput(!image.empty(), texture_path.string(), "cannot read the texture of scene " + path.string());
        it = textures.emplace(texture_path.string(), scene->AddTexture(Texture(image))).first;
      }
      material.texture = it->second;
      material.color = Vector3f(1, 1, 1);  // the texture carries the colour
      textured[i] = true;
    }
    materials[i] = scene->AddMaterial(material);
  }
  Eigen::Matrix3f to_town = Eigen::Matrix3f::Identity();
  if (options.y_up) to_town << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // (x, y, z) with y up -> (x, -z, y) with z up
  Mesh mesh;
  AddNode(ai, ai->mRootNode, aiMatrix4x4(), materials, textured, to_town, static_cast<float>(options.scale), &mesh);
  CheckInput(mesh.num_triangles() > 0, path.string(), "the scene file has no triangles");
  scene->AddStaticMesh(mesh);
}

}  // namespace retrace
